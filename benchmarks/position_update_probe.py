"""Microseconds per launch of the position update and of its parts, one kernel each.

    python benchmarks/position_update_probe.py [--arch cuda] [--scene pile_1000] [--launches 200]

On the first GPU run (docs/bench.md, "On a GPU") the position update's loop cost ~1 ms per
launch on CUDA whatever the body count, while every other body loop of a substep took 5-15 us.
This times ``integrate_positions`` beside kernels that each do one of its parts over the same
bodies (``error atomics``: the velocity check it used to have), and the update as it was until
2026-11-27 with one part left out at a time (``pose_without``), so the part that carries the
millisecond shows. On the second GPU run it was the two non-finite checks with their guarded
atomics (983-984 us with them, 88 us without); they now run once per step, at its end
(integrate.check_bodies_loops), so ``integrate_positions`` is now the update without them.
The kernels step by zero and scale the velocities by zero, so the bodies stay where they are (orientations are renormalised and the
gyroscopic variant rewrites angular velocities: a probe, not a simulation).
"""

import argparse
import time

import taichi as ti

from sandbox import Scene, World
from sandbox import integrate
from sandbox.awake import EVERY, body_id, body_total
from sandbox.math3d import any_nonfinite3, two_sum
from sandbox.scene.library import resolve_scene


@ti.kernel
def axpy(bodies: ti.template()):
    for i in range(bodies.count[None]):
        bodies.pos[i] = bodies.pos[i] + 0.0 * bodies.lin_vel[i]


@ti.kernel
def compensated_sum(bodies: ti.template()):
    for i in range(bodies.count[None]):
        x, rem = two_sum(bodies.pos[i], 0.0 * bodies.lin_vel[i] + bodies.pos_rem[i])
        bodies.pos[i] = x
        bodies.pos_rem[i] = rem


@ti.kernel
def moved_add(bodies: ti.template()):
    for i in range(bodies.count[None]):
        bodies.moved[i] += 0.0 * bodies.lin_vel[i]


@ti.kernel
def rotation(bodies: ti.template()):
    for i in range(bodies.count[None]):
        q, _ = integrate.rotate_free(bodies.rot[i], 0.0 * bodies.ang_vel[i], bodies.inertia[i],
                                     bodies.inv_inertia[i], 0.0, 0)
        bodies.rot[i] = q


@ti.kernel
def error_check(bodies: ti.template(), err: ti.template()):
    for i in range(bodies.count[None]):
        if any_nonfinite3(bodies.lin_vel[i]):
            ti.atomic_or(err.flags[None], integrate.ERR_VELOCITY)
            ti.atomic_min(err.body[None], i)


@ti.kernel
def pose_without(bodies: ti.template(), err: ti.template(), h: ti.f32, drop: ti.template()):
    """The non-gyroscopic position update as it was until 2026-11-27 (``advance_pose`` with its two
    non-finite checks, no damping) with the parts named in ``drop`` left out: the parts alone are
    cheap on CUDA, so the one whose removal takes the millisecond away is the cause."""
    for k in range(body_total(bodies, EVERY) if ti.static("body_total" not in drop) else bodies.count[None]):
        i = body_id(EVERY, k)
        if bodies.inv_mass[i] > 0.0:
            v = bodies.lin_vel[i]
            w = bodies.ang_vel[i]
            if ti.static("checks" not in drop):
                if any_nonfinite3(v) or any_nonfinite3(w):
                    ti.atomic_or(err.flags[None], integrate.ERR_VELOCITY)
                    ti.atomic_min(err.body[None], i)
            dx = h * v
            x = bodies.pos[i] + dx
            if ti.static("compensated sum" not in drop):
                x1, rem = two_sum(bodies.pos[i], dx + bodies.pos_rem[i])
                x = x1
                bodies.pos_rem[i] = rem
            if ti.static("moved +=" not in drop):
                bodies.moved[i] += dx
            q = bodies.rot[i]
            if ti.static("rotation" not in drop):
                q, _ = integrate.rotate_free(bodies.rot[i], w, bodies.inertia[i], bodies.inv_inertia[i], h, 0)
            if ti.static("checks" not in drop):
                if integrate.nonfinite_pose(x, q):
                    ti.atomic_or(err.flags[None], integrate.ERR_POSE)
                    ti.atomic_min(err.body[None], i)
            bodies.pos[i] = x
            bodies.rot[i] = q
            bodies.ang_vel[i] = w


ABLATIONS = ((), ("body_total",), ("checks",), ("compensated sum",), ("moved +=",), ("rotation",),
             ("checks", "moved +="), ("checks", "compensated sum", "moved +=", "rotation"))


def per_launch_us(kernel, *args, launches: int) -> float:
    kernel(*args)
    ti.sync()
    t = time.perf_counter()
    for _ in range(launches):
        kernel(*args)
    ti.sync()
    return 1e6 * (time.perf_counter() - t) / launches


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arch", default="cuda", choices=("cpu", "cuda"))
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--launches", type=int, default=200)
    a = ap.parse_args()
    world = World(Scene.load(resolve_scene(a.scene)), solver="mass-splitting", iterations=15, arch=a.arch)
    world.step(2)
    bodies, err = world.buf.bodies, world.buf.errors
    print(f"{a.scene} on {a.arch}: {bodies.count[None]} bodies")
    runs = [("integrate_velocities", integrate.integrate_velocities, (bodies, EVERY, ti.math.vec3(0.0), 0.0)),
            ("integrate_positions", integrate.integrate_positions, (bodies, EVERY, 0, 0.0)),
            ("integrate_positions, gyroscopic", integrate.integrate_positions,
             (bodies, EVERY, integrate.GYROSCOPIC, 0.0)),
            ("axpy", axpy, (bodies,)), ("compensated sum", compensated_sum, (bodies,)),
            ("moved +=", moved_add, (bodies,)), ("rotation", rotation, (bodies,)),
            ("error atomics", error_check, (bodies, err))]
    for name, kernel, args in runs:
        print(f"  {name:34s} {per_launch_us(kernel, *args, launches=a.launches):9.1f} us/launch", flush=True)
    print("the position update (h = 0), one part left out at a time:")
    for drop in ABLATIONS:
        us = per_launch_us(pose_without, bodies, err, 0.0, drop, launches=a.launches)
        print(f"  without {', '.join(drop) or 'nothing':30s} {us:9.1f} us/launch", flush=True)


if __name__ == "__main__":
    main()
