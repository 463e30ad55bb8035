"""Milliseconds per step of every kernel a step launches, on a settled scene.

    python benchmarks/kernel_times.py [--scene pile_1000] [--solver mass-splitting] [--iterations 15]
                                      [--settle 300] [--steps 30] [--launch auto] [--arch cpu]
                                      [--pair-reuse-margin M] [--tasks]

Each kernel that ``World.step`` launches (the fused set-up kernels of step_kernels.py,
the iteration loop, and the per-stage kernels where they still run) is wrapped with a
device sync before and after, so its time is its own. The syncs cost a little: compare
the sum with the synced wall time, and the unsynced ms/step printed last. Works on the
tree it is run from (so an older tree can be timed with the same script, as in
docs/bench.md "Second pass").

``--tasks`` also switches on Taichi's own kernel profiler (``TI_KERNEL_PROFILER=1``) and prints
the time of each offloaded task (a kernel's top-level loop or serial block: ``name_cN_0_kernel_K``,
K counting them in source order) over the timed steps. On CUDA that is how the position update's
~1 ms launch was found (docs/bench.md, "On a GPU").

``--launch per-stage`` times each stage of a substep as a launch of its own, the light bodies'
extra sweeps (``Settings.ratio_sweeps``) included, which then launch whether or not a light body
touches a heavy one: on the CPU each launch's parallel loops are thread-pool dispatches (~30-50 us
on a 2-core VM, benchmarks/loop_dispatch.py), so a nearly empty sweep shows as time. On ``pile_1000``
after 300 steps (6 of its ~4 800 blocks listed, two light bodies) ``light_sweep`` read 36 % of the
per-stage kernel time, nearly all of it dispatch; the shipped launch runs those loops inside its one
kernel, over the short lists.
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import time

import taichi as ti

from sandbox import Scene, World
from sandbox.scene.library import resolve_scene

WRAPPED = {
    "sandbox.step_kernels": ["begin_and_collide", "prepare_step", "finish_step", "solve_step_in_order",
                             "solve_step_shared"],
    "sandbox.broadphase": ["build_dynamic_grid"],
    "sandbox.pair_search": ["find_pairs"],
    "sandbox.contacts": ["collide_pairs"],
    "sandbox.persistence": ["match_contacts", "store_contacts"],
    "sandbox.bodies": ["update_world_inertia", "save_good_state"],
    "sandbox.integrate": ["check_bodies"],
    "sandbox.solvers.rows": ["prepare_rows", "prepare_response"],
    "sandbox.solvers.mass_splitting": ["build_adjacency"],
    "sandbox.solvers.substep": ["iterate_in_order"],
    "sandbox.solvers.team_loop": ["iterate_shared"],
}


def main() -> None:
    import importlib

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--solver", default="mass-splitting")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=300)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--launch", default="auto", help="Settings.iteration_launch")
    ap.add_argument("--reuse-distance", type=float, default=None,
                    help="Settings.manifold_reuse_distance [m] (0: every pair through SAT and clipping)")
    ap.add_argument("--pair-reuse-margin", type=float, default=None, help="Settings.pair_reuse_margin [m]")
    ap.add_argument("--arch", default="cpu", choices=("cpu", "cuda"))
    ap.add_argument("--tasks", action="store_true", help="Taichi's kernel profiler: time of each offloaded task")
    a = ap.parse_args()
    if a.tasks:
        os.environ["TI_KERNEL_PROFILER"] = "1"  # read by ti.init (backend.init) from the environment
    total = collections.defaultdict(float)
    timing = [False]

    def wrap(mod, name):
        f = getattr(mod, name)

        def timed(*args, **kw):
            if not timing[0]:
                return f(*args, **kw)
            ti.sync()
            t = time.perf_counter()
            out = f(*args, **kw)
            ti.sync()
            total[name] += time.perf_counter() - t
            return out

        # also where a module imported the name itself (step.py calls check_bodies, store_contacts...)
        for other in list(sys.modules.values()):
            if getattr(other, "__name__", "").startswith("sandbox") and getattr(other, name, None) is f:
                setattr(other, name, timed)

    for module, names in WRAPPED.items():
        try:
            mod = importlib.import_module(module)
        except ImportError:  # an older tree
            continue
        for name in names:
            if hasattr(mod, name):
                wrap(mod, name)
    from sandbox import Settings

    settings = Settings(iteration_launch=a.launch)
    if a.reuse_distance is not None:
        settings = settings.replace(manifold_reuse_distance=a.reuse_distance)
    if a.pair_reuse_margin is not None:
        settings = settings.replace(pair_reuse_margin=a.pair_reuse_margin)
    world = World(Scene.load(resolve_scene(a.scene)), solver=a.solver, iterations=a.iterations, arch=a.arch,
                  settings=settings)
    world.step(a.settle)
    b = world.buf
    print(f"{a.scene} {a.solver} {a.iterations} iterations, after {a.settle} steps: pairs {b.bp.pair_total[None]} "
          f"({b.bp.searched[None]} of {b.shapes.dynamic_count[None]} shapes searched), "
          f"contact points {b.contacts.count[None]}, manifolds {b.contacts.manifold_count[None]}")
    if a.tasks:
        ti.profiler.clear_kernel_profiler_info()
    timing[0] = True
    ti.sync()
    t = time.perf_counter()
    world.step(a.steps)
    ti.sync()
    wall = time.perf_counter() - t
    timing[0] = False
    if a.tasks:
        ti.profiler.print_kernel_profiler_info("count")
    for name, s in sorted(total.items(), key=lambda kv: -kv[1]):
        print(f"  {name:22s} {1e3 * s / a.steps:7.3f} ms")
    print(f"  {'sum':22s} {1e3 * sum(total.values()) / a.steps:7.3f} ms   wall (synced) {1e3 * wall / a.steps:7.3f} ms")
    ti.sync()
    t = time.perf_counter()
    world.step(a.steps)
    ti.sync()
    print(f"  unsynced {1e3 * (time.perf_counter() - t) / a.steps:.3f} ms/step")


if __name__ == "__main__":
    main()
