"""What one substep of a settled scene costs in the running step, and what the rest of the step does.

    python benchmarks/substep_cost.py [--scene pile_1000] [--solver mass-splitting] [--settle 300]
                                      [--counts 8,15,30] [--rounds 6] [--steps 20] [--set NAME=VALUE ...]
    TI_CPU_MAX_NUM_THREADS=1 python benchmarks/substep_cost.py    # the same on one thread

Builds the scene's world (CPU), steps it ``--settle`` times at 15 iterations, then times
``--steps`` whole steps (``World.step``, collision included) at each of ``--counts`` iterations,
switched live, round after round (the VM's speed drifts: the best block of ``--rounds`` counts).
One iteration is one substep, so the slope of ms/step between the lowest and the highest count is
one substep's cost in the running step (all counts at 8 or more: below, a substep sweeps more
than once, formulation.sweep_plan), and what is left at zero iterations the rest of the step.

Beside it, ``python benchmarks/lane_sweep.py`` times a substep's parts alone on one thread (the
biased and the relax lane sweep, a gather of the bodies' slots, two a substep); the gap between
their sum and the substep measured here is what the substep pays besides them (docs/bench.md,
"Thirteenth pass"). ``--set`` changes a ``Settings`` field (a Python literal), as in
step_bench.py: ``--set ratio_sweeps=0`` prices the light bodies' extra sweeps.
"""

import argparse
import ast
import time

import taichi as ti

from sandbox import Scene, Settings, World, backend
from sandbox.scene.library import resolve_scene


def whole_steps(world: World, solver: str, counts: list[int], rounds: int, steps: int) -> dict[int, float]:
    """Best ms/step at each iteration count, the counts interleaved round by round."""
    best = {k: float("inf") for k in counts}
    for k in counts:  # compile and settle into each count once, untimed
        world.set_solver(solver, iterations=k)
        world.step(3)
    for _ in range(rounds):
        for k in counts:
            world.set_solver(solver, iterations=k)
            world.step(2)
            ti.sync()
            t = time.perf_counter()
            world.step(steps)
            ti.sync()
            best[k] = min(best[k], (time.perf_counter() - t) / steps * 1e3)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--solver", default="mass-splitting")
    ap.add_argument("--settle", type=int, default=300)
    ap.add_argument("--counts", default="8,15,30", help="iteration counts, 8 or more")
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="a Settings field")
    a = ap.parse_args()
    changes = {name: ast.literal_eval(value) for name, _, value in (item.partition("=") for item in a.set)}
    counts = sorted(int(x) for x in a.counts.split(","))
    if len(counts) < 2 or counts[0] < 8:
        ap.error("--counts needs two or more counts, all 8 or more")
    backend.init("cpu")
    from sandbox.cpu_workers import cpu_threads

    scene = Scene.load(resolve_scene(a.scene))
    settings = Settings().replace(**{**scene.world.settings_given(), **changes}) if changes else None
    world = World(scene, solver=a.solver, iterations=15, arch="cpu", settings=settings)
    world.step(a.settle)
    best = whole_steps(world, a.solver, counts, a.rounds, a.steps)
    lo, hi = counts[0], counts[-1]
    per_substep = (best[hi] - best[lo]) / (hi - lo)
    print(f"{a.scene}, {a.solver}" + "".join(f", {k}={v!r}" for k, v in changes.items())
          + f", after {a.settle} steps, {cpu_threads()} Taichi CPU thread(s), "
          f"{int(world.buf.blocks.block_count[None])} blocks, {int(world.buf.bodies.count[None])} bodies")
    print("whole step: " + ", ".join(f"{k} iterations {best[k]:.2f} ms" for k in counts))
    print(f"one substep {per_substep * 1e3:.0f} us, the rest of the step {best[lo] - lo * per_substep:.2f} ms")


if __name__ == "__main__":
    main()
