"""Per-stage cost of a step, for every solver, on the shipped pyramid and 1000-box pile.

    python benchmarks/step_bench.py [--scenes pyramid_20,pile_1000] [--solvers ...]
                                    [--iterations 15] [--settle 120] [--steps 120] [--arch cpu]
                                    [--set NAME=VALUE ...]

Protocol: build the world, run ``--settle`` steps (compiles every kernel and lets
the scene reach a representative contact count), then time ``--steps`` steps
twice: once with the profiler on (ms/step by stage; the profiler runs the step stage by
stage, a launch per phase, so these columns carry launch and dispatch costs the fast path
does not pay) and once without (whole-step wall time -> ms/step and steps/s, the numbers
to compare with other engines). ``loop`` is the iteration loop of the fast path (its
launch(es) with a device sync on each side; where the step's set-up, solve and store are one
launch, step_kernels.solve_step_in_order / solve_step_shared, that launch, set-up and store
included) and ms/iter = loop / iterations. Compile time is reported apart. ``--set`` changes a
``Settings`` field (a Python literal), e.g. ``--set ratio_sweeps=0`` for the cost of a switch.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import importlib
import platform
import time

import taichi as ti

from sandbox import SOLVERS, Scene, Settings, World
from sandbox.scene.library import resolve_scene

ITERATION_KERNELS = {"sandbox.solvers.substep": ("iterate_in_order", "substep_parallel"),
                     "sandbox.solvers.team_loop": ("iterate_shared",),
                     "sandbox.step_kernels": ("solve_step_in_order", "solve_step_shared")}
_loop_seconds = [0.0]


@contextlib.contextmanager
def _timed_iteration_kernels():
    """The iteration loop's kernels wrapped with synced timers (summed into _loop_seconds) inside
    the block only: the fast path's wall time is taken without them, since two syncs a launch
    stall a GPU's queue and add a host round trip to a small CPU step."""
    saved = []
    for module_name, names in ITERATION_KERNELS.items():
        module = importlib.import_module(module_name)
        for name in names:
            saved.append((module, name, getattr(module, name)))
            _wrap(module, name)
    try:
        yield
    finally:
        for module, name, kernel in saved:
            setattr(module, name, kernel)


def _wrap(module, name: str) -> None:
    """``module.name`` replaced by the same kernel between two syncs, its time summed."""
    kernel = getattr(module, name)

    def timed(*args, **kw):
        ti.sync()
        t = time.perf_counter()
        kernel(*args, **kw)
        ti.sync()
        _loop_seconds[0] += time.perf_counter() - t

    setattr(module, name, timed)


def bench(scene_name: str, solver: str, iterations: int, settle: int, steps: int, arch: str,
          changes: dict | None = None) -> dict:
    scene = Scene.load(resolve_scene(scene_name))
    settings = Settings().replace(**{**scene.world.settings_given(), **changes}) if changes else None
    t0 = time.perf_counter()
    world = World(scene, solver=solver, iterations=iterations, arch=arch, profile=False, settings=settings)
    world.step(1)
    compile_s = time.perf_counter() - t0
    world.step(settle - 1)
    world.profiler.enabled = True
    world.step(1)  # profiled steps run the iteration loop stage by stage: compile it outside the timing
    world.profiler.reset()
    world.step(steps)
    stages = world.timing_ms()
    world.profiler.enabled = False
    ti.sync()
    t = time.perf_counter()
    world.step(steps)
    ti.sync()
    wall = time.perf_counter() - t
    _loop_seconds[0] = 0.0
    with _timed_iteration_kernels():
        world.step(steps)
    loop = _loop_seconds[0]
    m = world.metrics()
    return {"scene": scene_name, "solver": solver, "iterations": iterations, "bodies": world.body_count,
            "contacts": m["contacts"], "stages": stages, "ms_per_step": 1e3 * wall / steps,
            "steps_per_s": steps / wall, "loop_ms": 1e3 * loop / steps, "compile_s": compile_s,
            "ke": m["kinetic_energy"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="pyramid_20,pile_1000")
    ap.add_argument("--solvers", default=",".join(SOLVERS))
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=120)
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--arch", default="cpu")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a Settings field")
    a = ap.parse_args()
    changes = {}
    for item in a.set:
        name, _, value = item.partition("=")
        changes[name] = ast.literal_eval(value)
    Settings().replace(**changes)  # a wrong name or value fails here, before any world
    print(f"# {platform.processor() or platform.machine()}, {platform.python_version()}, arch={a.arch}, "
          f"iterations={a.iterations}, settle={a.settle}, timed steps={a.steps}"
          + "".join(f", {k}={v!r}" for k, v in changes.items()))
    print(f"{'':54s}{'profiled, ms/step by stage':^34s}  {'fast path':^34s}")
    hdr = (f"{'scene':12s} {'solver':22s} {'bodies':>6s} {'contacts':>8s}  {'collide':>8s} {'prepare':>8s} "
           f"{'solve':>8s} {'integr':>7s}  {'loop':>7s} {'ms/iter':>8s} {'ms/step':>8s} {'steps/s':>8s} "
           f"{'compile s':>9s}")
    print(hdr)
    for scene in a.scenes.split(","):
        for solver in a.solvers.split(","):
            r = bench(scene, solver, a.iterations, a.settle, a.steps, a.arch, changes)
            s = r["stages"]
            print(f"{scene:12s} {solver:22s} {r['bodies']:6d} {r['contacts']:8d}  {s['collide']:8.2f} "
                  f"{s['prepare']:8.2f} {s['solve']:8.2f} {s['integrate']:7.2f}  {r['loop_ms']:7.2f} "
                  f"{r['loop_ms'] / a.iterations:8.3f} {r['ms_per_step']:8.2f} {r['steps_per_s']:8.1f} "
                  f"{r['compile_s']:9.1f}", flush=True)


if __name__ == "__main__":
    main()
