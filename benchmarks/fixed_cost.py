"""What a step costs once, whatever the iteration count: the parts of the shared solve launch.

    python benchmarks/fixed_cost.py [--scene pyramid_20] [--settle 100] [--rounds 2]

``benchmarks/substep_cost.py`` splits a step into its substeps and "the rest"; on the pyramid the
rest is about half the step at 15 iterations. This says where it goes, on a world whose iteration
loop the CPU threads share (``step_kernels.solve_step_shared``; mass splitting at 15 iterations):
the scene is stepped ``--settle`` times, the solve launch's arguments are kept, and then each part
runs as a kernel of its own, 200 launches a block, best of five blocks (microseconds a launch):

* the whole solve launch with 0, 1 and 2 substeps (the step's scalars set to that count), and with 0
  as it was laid out before the team took over the set-up (docs/bench.md, "Twenty-second pass");
* the set-up alone (``prepare_step_loops``, responses left to the team as in the shared launch), the
  store and checks alone (``step_kernels.finish_step``);
* the team with 0 substeps (its wake-up, counter reset and lane copy with the rows' responses),
  its wake-up and reset alone, the lane copy with and without the responses;
* the collision (``begin_and_collide``) and an empty kernel with the solve's arguments (what a
  launch costs before it does anything).

Each part's own work is its figure less the empty launch. The world is not held still: the
launches with substeps move it a little on its last contacts and each collision launch redoes the
step's collision, so the parts are timed near the settled state, not at it. A diagnostic of the
running code (it reaches into ``World``'s buffers), not of the API; figures in docs/bench.md,
"Twenty-first pass" and "Twenty-second pass".
"""

import argparse
import time

import taichi as ti

from sandbox import Scene, World, step_kernels
from sandbox.scene.library import resolve_scene
from sandbox.solvers import team as tm
from sandbox.solvers.point_lanes import lane_copy_phase
from sandbox.solvers.team_loop import goes_in_lanes, iterate_shared_loops
from sandbox.step import speculation
from sandbox.step_kernels import finish_step_loops, prepare_step_loops
from sandbox.step_scalars import (BIASED_SWEEPS, MATCH_DISTANCE, RELAX_SWEEPS, RELAXATION, SLEEP_ANGULAR,
                                  SLEEP_LINEAR, SLEEP_TIME, STEP, SUBSTEP, SUBSTEPS, WARM_FACTOR)

_woken = None  # a field the wake-up kernel writes, made after ti.init (main)


@ti.kernel
def _prepare(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32, awake: ti.template(),
             dispatch: ti.template()):
    f = ti.static(b.scalars.f)
    in_team = ti.static(goes_in_lanes(sw.visit, sw.kind, sw.friction))
    prepare_step_loops(b, b.blocks, f[MATCH_DISTANCE], f[WARM_FACTOR], sw.kind, sw.mode, f[RELAXATION], sw.split,
                       sw.friction, dispatch, not in_team)


@ti.kernel
def _solve_set_up_apart(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32,
                        awake: ti.template(), dispatch: ti.template()):
    """The solve launch as it was until the twenty-second pass: the set-up's loops before the team,
    not its first phases (step_kernels.solve_step_shared); the same bits."""
    f, n = ti.static(b.scalars.f, b.scalars.i)
    in_team = ti.static(goes_in_lanes(sw.visit, sw.kind, sw.friction))
    prepare_step_loops(b, b.blocks, f[MATCH_DISTANCE], f[WARM_FACTOR], sw.kind, sw.mode, f[RELAXATION], sw.split,
                       sw.friction, dispatch, not in_team)
    iterate_shared_loops(team, b, sw.kind, sw.visit, sw.friction, sw.warm, sw.track, awake, sw.motion, f[SUBSTEP],
                         n[SUBSTEPS], n[BIASED_SWEEPS], n[RELAX_SWEEPS], members, in_team, sw.split)
    finish_step_loops(b, sw.kind, n[SUBSTEPS], awake, f[STEP], f[SLEEP_LINEAR], f[SLEEP_ANGULAR], f[SLEEP_TIME],
                      dispatch)


@ti.kernel
def _team(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32, awake: ti.template(),
          dispatch: ti.template()):
    f, n = ti.static(b.scalars.f, b.scalars.i)
    in_team = ti.static(goes_in_lanes(sw.visit, sw.kind, sw.friction))
    iterate_shared_loops(team, b, sw.kind, sw.visit, sw.friction, sw.warm, sw.track, awake, sw.motion, f[SUBSTEP],
                         n[SUBSTEPS], n[BIASED_SWEEPS], n[RELAX_SWEEPS], members, in_team, sw.split)


@ti.kernel
def _wake(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32, awake: ti.template(),
          dispatch: ti.template()):
    tm.reset_loop(team, ti.static(team.claimed.shape[0]))
    for i in range(members * tm.TASK_ITEMS):
        if i % tm.TASK_ITEMS == 0:
            _woken[i // tm.TASK_ITEMS] = 1


@ti.kernel
def _copy(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32, awake: ti.template(),
          dispatch: ti.template(), responds: ti.template()):
    tm.reset_loop(team, ti.static(team.claimed.shape[0]))
    for i in range(members * tm.TASK_ITEMS):
        if i % tm.TASK_ITEMS == 0:
            lane_copy_phase(team, 0, i // tm.TASK_ITEMS, members, b.lanes, b.blocks, b.rows, b.contacts, b.bodies,
                            responds, sw.split, sw.friction)


@ti.kernel
def _empty(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32, awake: ti.template(),
           dispatch: ti.template()):
    pass


def best_us(run, launches: int = 200, blocks: int = 5) -> float:
    best = float("inf")
    for _ in range(blocks):
        ti.sync()
        t = time.perf_counter()
        for _ in range(launches):
            run()
        ti.sync()
        best = min(best, (time.perf_counter() - t) / launches)
    return best * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pyramid_20")
    ap.add_argument("--settle", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=2)
    a = ap.parse_args()
    kept = {}
    shared = step_kernels.solve_step_shared

    def keep(*args):
        kept["args"] = args
        return shared(*args)

    step_kernels.solve_step_shared = keep
    world = World(Scene.load(resolve_scene(a.scene)), solver="mass-splitting", iterations=15, arch="cpu")
    world.step(a.settle)
    step_kernels.solve_step_shared = shared
    if "args" not in kept:
        raise SystemExit(f"{a.scene}: no step shared its iteration loop between threads (--settle 0, or one "
                         f"Taichi thread?)")
    args = kept["args"]
    global _woken
    _woken = ti.field(ti.i32, max(args[3], 1))  # one entry a team member
    b = args[0]
    edits = world._edits
    counts = b.scalars.i
    substeps = int(counts[SUBSTEPS])
    print(f"{a.scene}, mass splitting, 15 iterations, after {a.settle} steps: {b.contacts.count[None]} points, "
          f"{args[3]} team members; microseconds a launch, best of 5 blocks of 200")

    def with_substeps(k, run):
        def go():
            counts[SUBSTEPS] = k
            try:
                return best_us(run)
            finally:
                counts[SUBSTEPS] = substeps
        return go

    parts = {
        "solve launch, 0 substeps": with_substeps(0, lambda: shared(*args)),
        "solve launch, 1 substep": with_substeps(1, lambda: shared(*args)),
        "solve launch, 2 substeps": with_substeps(2, lambda: shared(*args)),
        "the same, 0 substeps, set-up before the team": with_substeps(0, lambda: _solve_set_up_apart(*args)),
        "set-up alone": lambda: best_us(lambda: _prepare(*args)),
        "store and checks alone": lambda: best_us(lambda: step_kernels.finish_step(b, args[1].kind, args[4], args[5])),
        "team, 0 substeps": with_substeps(0, lambda: _team(*args)),
        "team wake-up and reset": lambda: best_us(lambda: _wake(*args)),
        "lane copy with responses": lambda: best_us(lambda: _copy(*args, True)),
        "lane copy alone": lambda: best_us(lambda: _copy(*args, False)),
        "collision": lambda: best_us(lambda: step_kernels.begin_and_collide(b, speculation(edits.settings), edits.kinds,
                                                                            args[4], edits.dispatch)),
        "empty launch": lambda: best_us(lambda: _empty(*args)),
    }
    for part in parts.values():  # compile every kernel before timing
        part()
    for r in range(a.rounds):
        print(f"round {r + 1}: " + "  ".join(f"{name} {part():.1f}" for name, part in parts.items()), flush=True)


if __name__ == "__main__":
    main()
