"""The sandbox's sweep of per-point blocks on one CPU core: point by point against eight at a time.

    python benchmarks/lane_sweep.py [--scene pile_1000] [--solver mass-splitting] [--iterations 15]
                                    [--settle 300] [--repeats 50]

Builds the scene's world, steps it ``--settle`` times, and then sweeps its contact points from the
same velocities with mass_splitting.sweep_block (one point per loop item, the path every launch
but the CPU team's takes) and with point_lanes.sweep_point_lanes (eight points per item, the
team's path), a biased and a relax sweep each, on one thread. Prints nanoseconds per point update
(the best of five runs of ``--repeats`` sweeps) and checks that the two leave the same impulses,
separations (a relax sweep keeps them) and slots, bit for bit. The team's loop also copies the
rows into groups once a step, and after each sweep every body gathers its slots
(mass_splitting.gather_body): both timed too, the gather per pass over the bodies
(benchmarks/substep_cost.py sets these parts beside a substep's cost in the running step).
"""

import argparse
import time

import numpy as np
import taichi as ti

from sandbox import Scene, World, backend
from sandbox.scene.library import resolve_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--solver", default="mass-splitting", choices=("mass-splitting", "jacobi"))
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=50)
    a = ap.parse_args()
    backend.init("cpu")
    from sandbox.lanes import LANES
    from sandbox.solvers.block_adjacency import PER_POINT
    from sandbox.solvers.mass_splitting import gather_body, sweep_block
    from sandbox.solvers.point_lanes import copy_group, sweep_point_lanes
    from sandbox.solvers.rows import BIASED, RELAX, contact_switch

    world = World(Scene.load(resolve_scene(a.scene)), solver=a.solver, iterations=a.iterations)
    world.step(a.settle)
    b = world.buf
    lanes = b.lane_rows()  # allocated by the team's first step; here too when --settle 0 ran none
    friction = contact_switch(world.compiled_effects)

    @ti.kernel
    def copy_rows(repeats: ti.i32):
        ti.loop_config(serialize=True)
        for _ in range(repeats):
            n = b.blocks.block_count[None]
            for g in range((n + LANES - 1) // LANES):
                copy_group(lanes, b.blocks, b.rows, b.contacts, g, n)

    @ti.kernel
    def by_point(repeats: ti.i32, mode: ti.template()):
        ti.loop_config(serialize=True)
        for _ in range(repeats):
            for k in range(b.blocks.block_count[None]):
                sweep_block(b.blocks, b.rows, b.contacts, b.bodies, PER_POINT, mode, friction, 0, k, 0)

    @ti.kernel
    def lanes_kernel(repeats: ti.i32, biased: ti.i32):
        ti.loop_config(serialize=True)
        for _ in range(repeats):
            n = b.blocks.block_count[None]
            for g in range((n + LANES - 1) // LANES):
                sweep_point_lanes(lanes, b.blocks, b.rows, b.contacts, b.bodies, biased, friction, 0, g, n)

    @ti.kernel
    def gather(repeats: ti.i32):
        ti.loop_config(serialize=True)
        for _ in range(repeats):
            for i in range(b.bodies.count[None]):
                gather_body(b.blocks, b.bodies, ti.math.vec3(0.0), i)

    def by_lanes(repeats: int, mode: int) -> None:  # the kind of sweep a run-time value, as in the team's loop
        lanes_kernel(repeats, int(mode == BIASED))

    def best(fn, *args) -> float:
        fn(1, *args)
        ti.sync()
        times = []
        for _ in range(5):
            t = time.perf_counter()
            fn(a.repeats, *args)
            ti.sync()
            times.append(time.perf_counter() - t)
        return min(times) / a.repeats

    n = int(b.blocks.block_count[None])
    print(f"{a.scene}, {a.solver}, {a.iterations} iterations, after {a.settle} steps: {n} contact points, one thread")
    print(f"copy into groups (once a step)  {best(copy_rows) / n * 1e9:6.1f} ns per point")
    lam0, sep0 = b.rows.lam.to_numpy(), b.rows.sep_now.to_numpy()
    same = True
    for name, mode in (("biased", BIASED), ("relax", RELAX)):
        results = []
        for fn in (by_point, by_lanes):
            b.rows.lam.from_numpy(lam0)
            b.rows.sep_now.from_numpy(sep0)
            fn(1, mode)
            results.append((b.rows.lam.to_numpy()[:n], b.rows.sep_now.to_numpy()[:n], b.blocks.slots.to_numpy()))
        (lam_p, sep_p, slots_p), (lam_l, sep_l, slots_l) = results
        groups = -(-n // LANES)
        lanes_kept = np.arange(groups * LANES) < n  # a last group's lanes past the count are never read
        kept = slots_p[:, :groups].transpose(0, 1, 3, 2)[:, lanes_kept.reshape(groups, LANES)]
        kept_l = slots_l[:, :groups].transpose(0, 1, 3, 2)[:, lanes_kept.reshape(groups, LANES)]
        same &= np.array_equal(lam_p, lam_l) and np.array_equal(sep_p, sep_l) and np.array_equal(kept, kept_l)
        t_point, t_lanes = best(by_point, mode), best(by_lanes, mode)
        print(f"{name:6s} sweep: point by point {t_point / n * 1e9:6.1f} ns per point, eight at a time "
              f"{t_lanes / n * 1e9:6.1f} ({t_point / t_lanes:.2f}x)")
    b.rows.lam.from_numpy(lam0)
    b.rows.sep_now.from_numpy(sep0)
    bodies = int(b.bodies.count[None])
    print(f"gather of the slots: {best(gather) * 1e6:6.1f} us per pass over the {bodies} bodies (two a substep)")
    print(f"impulses, separations and slots bit for bit the same: {same}")


if __name__ == "__main__":
    main()
