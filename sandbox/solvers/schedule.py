"""A solver description (``SolverInfo``) turned into kernel calls: the per-step set-up, the
warm start, one sweep, and the whole iteration loop in each launch mode.

Everything that depends on which solver runs is decided here from the description's
fields, never from its name: how a sweep visits the rows (``pgs.py`` serial or by colour,
``mass_splitting.py`` all blocks at once), the block kind, the merge mode and relaxation
of the body adjacency, whether the rows' responses are scaled, whether the manifolds are
coloured, and which launches of the iteration loop (``substep.py``) the schedule allows.
The kernels' long argument lists are written once, from a ``Loop`` (the buffers and
compile-time switches of one step's iteration loop).

Kernels are looked up on their modules at every call (``team_loop.iterate_shared``, not
a name imported once), so the benchmarks can wrap them with timers.
"""

from __future__ import annotations

from dataclasses import dataclass

import taichi as ti

from ..formulation import PAPER, sweep_plan
from ..settings import MAX_STEP_SWEEPS
from . import SOLVERS, block_adjacency, mass_splitting, pgs, step_impulses, substep, team, team_loop
from . import rows as contact_rows

_VISIT = {"serial": substep.PGS, "colored": substep.PGS_COLORED, "blocks": substep.BLOCKS}
_BLOCK = {"point": block_adjacency.PER_POINT, "manifold": block_adjacency.PER_MANIFOLD}
ONE_THREAD_BODY_LIMIT = 64
"""On the CPU, "auto" runs the iteration loop on one thread in a world whose buffers hold at
most this many bodies, and shares it between the threads in larger ones: each of the shared
loop's phases ends at a barrier where the threads wait for each other, which a few dozen
bodies do not pay for. Measured (mass splitting, 15 iterations, unsynced ms/step, one run):
shared against one thread, friction_arch (24 pairs) 0.76 / 0.68, mass_ratio_stacks (12) 0.72 /
0.59, stack_20 at 4 iterations 0.23 / 0.12 ms for the loop alone; the playground (164 pairs)
0.75 / 0.67, but pyramid_20 (590) 2.44 / 3.53. The choice follows the buffer class, not the
step's pair count: a world that crossed a pair threshold would compile the other launch in the
middle of a run (a 0.9-1.7 s stall measured in the web sandbox after a debris drop)."""


def _merge_mode(info, options: dict) -> int:
    """How the adjacency scales a block's bodies (mass_splitting.py): each body's own split, the
    ``jacobi`` solver's global factor bounded by its busiest body's split, or one fixed factor (an
    explicit Jacobi ``relaxation``; the in-place schedules, whose warm start alone uses the merge)."""
    if info.splits_masses:
        return block_adjacency.MODE_SPLIT
    if info.combine == "jacobi" and options.get("relaxation") is None:
        return block_adjacency.MODE_JACOBI_BOUNDED
    return block_adjacency.MODE_JACOBI


_FALLBACK = {"shared": "one", "per-substep": "per-stage"}
"""The launch to use instead when a schedule cannot run the one asked for (SolverInfo.launches)."""


@dataclass(frozen=True)
class Loop:
    """One step's iteration loop: the buffers, the compile-time switches and the substep."""

    buf: object  # buffers.BufferSet
    friction: int  # which friction rows are solved: rows.SLIDING | rows.ROLLING bits (rows.contact_switch)
    warm: bool  # last step's impulses warm start the first substep
    track: bool  # each substep's impulses are summed into the step's (rows.lam_step)
    gravity: object  # ti.math.vec3 [m/s^2]
    h: float  # substep [s]
    iterations: int  # substeps per step
    sweeps: int  # biased sweeps per substep (formulation.sweep_plan)
    relax: int  # relax sweeps per substep (0 under the paper formulation)
    awake: object  # which bodies the body loops visit: awake.EVERY, or a sleeping world's awake lists
    motion: int = 1  # the position update's switches (integrate.motion_switch: gyroscopic, damping)
    ratio: int = 0  # extra biased sweeps of light bodies' blocks per substep, at most (formulation.SweepPlan)


class Schedule:
    """The calls of one solver choice (``name``, ``options`` as ``check_solver`` returns them)."""

    def __init__(self, name: str, options: dict):
        self.info = SOLVERS[name]
        self.options = dict(options)
        self.visit = _VISIT[self.info.visit]
        self.kind = _BLOCK[self.info.block]
        self.mode = _merge_mode(self.info, self.options)
        self._color_starts = None  # this step's colour ranges, read once by the first sweep that needs them
        self._color_count = 0

    # ------------------------------------------------------------------ per step
    def relaxation(self, settings) -> float:
        """omega of the merge: the ``relaxation`` option, else the setting the description names
        (under the paper formulation the split schedules take the paper's plain average, 1)."""
        given = self.options.get("relaxation")
        if given is not None:
            return float(given)
        name = self.info.relaxation_setting
        if name == "split_relaxation" and settings.formulation == PAPER:
            return 1.0
        return float(getattr(settings, name)) if name else 1.0

    def ratio_sweeps(self, settings, light_bodies: bool = True) -> int:
        """Settings.ratio_sweeps for the Jacobi family, whose split sweep moves a heavy body's load
        into a light one a share at a time; 0 for the PGS solvers and in a world without a light
        body (``light_bodies``: CompiledEffects.light_bodies)."""
        return settings.ratio_sweeps if self.visit == substep.BLOCKS and light_bodies else 0

    def plan(self, settings, iterations: int, light_bodies: bool = True):
        """This schedule's formulation.SweepPlan for a step of ``iterations`` under ``settings``."""
        ratio = self.ratio_sweeps(settings, light_bodies)
        return sweep_plan(settings.formulation, iterations, settings.sweeps, ratio, settings.step_sweeps)

    def adjacency_args(self, buf, settings) -> tuple:
        """(block scratch, kind, mode, omega, scaled responses): the schedule's arguments of
        ``build_adjacency`` / ``prepare_response`` (the fused step kernels read the block scratch
        as ``b.blocks`` and omega from ``b.scalars``, step_scalars.py)."""
        return buf.blocks, self.kind, self.mode, self.relaxation(settings), self.info.scales_masses

    def prepare(self, buf, settings, step: int, friction: int) -> None:
        """After the rows: body adjacency, scaled responses and colouring, as separate launches."""
        blk, kind, mode, omega, scaled = self.adjacency_args(buf, settings)
        block_adjacency.build_adjacency(blk, buf.contacts, buf.bodies, buf.rows, kind, mode, omega)
        contact_rows.prepare_response(buf.rows, buf.contacts, buf.bodies, blk, scaled, friction)
        self.color(buf, step)

    def color(self, buf, step: int) -> None:
        """Colour this step's manifolds when the schedule visits by colour (seeded by the step)."""
        if self.info.needs_coloring:
            shuffle, seed = int(self.options["shuffle"]), int(self.options["seed"])
            pgs.color_manifolds(buf.coloring, buf.contacts, buf.bodies, shuffle, seed, step)
        self._color_starts = None

    def color_count(self, buf) -> int | None:
        """Colours used in the last step; None when the schedule does not colour."""
        return int(buf.coloring.color_count[None]) if self.info.needs_coloring else None

    # ------------------------------------------------------------------ stage by stage
    def folds_warm_start(self, warm: bool) -> bool:
        """Gravity and warm start of a later substep ride on the previous relax sweep (in a step
        with an impact row its carries are clamped after it: mass_splitting.clamp_folded_carries)."""
        return substep.folds_warm_start(self.visit, warm)

    def warm_start(self, buf, awake, friction: int, gravity, h: float) -> None:
        """Gravity, then last step's matched impulses with the full masses, as one launch."""
        mass_splitting.warm_start(buf.blocks, buf.rows, buf.contacts, buf.bodies, awake, self.kind, friction, gravity,
                                  h)

    def sweep(self, buf, awake, mode: int, friction: int, then_warm: int = 0, gravity=None, h: float = 0.0,
              substep: int = 0, light_only: int = 0) -> None:
        """One pass over every contact row (``then_warm``: mass_splitting.sweep_blocks), in substep
        ``substep`` of the step (visit_order.visited_point); ``light_only``: over the blocks of light
        bodies only (an extra sweep of the Jacobi family, Settings.ratio_sweeps)."""
        rows, c, bodies = buf.rows, buf.contacts, buf.bodies
        if self.info.visit == "serial":
            pgs.pgs_serial(rows, c, bodies, mode, friction, substep)
        elif self.info.visit == "colored":
            col, overflow = buf.coloring, pgs.MAX_COLORS
            if self._color_starts is None:  # one launch per colour: the ranges come to the host once a step
                self._color_starts = pgs.color_ranges(col)
                self._color_count = int(col.color_count[None])
            starts = self._color_starts
            for k in range(self._color_count):
                pgs.solve_color(rows, c, bodies, col, int(starts[k]), int(starts[k + 1]), mode, friction, substep)
            if starts[overflow + 1] > starts[overflow]:
                pgs.solve_overflow(rows, c, bodies, col, int(starts[overflow]), int(starts[overflow + 1]), mode,
                                   friction, substep)
        elif light_only:
            mass_splitting.light_sweep(buf.blocks, rows, c, bodies, self.kind, friction, substep)
        else:
            g = gravity if gravity is not None else ti.math.vec3(0.0)
            mass_splitting.jacobi_sweep(buf.blocks, rows, c, bodies, awake, self.kind, mode, friction, then_warm, g, h,
                                        substep)

    def restitution(self, buf, awake, friction: int, tolerance: float, max_sweeps: int) -> int:
        """The bounce pass after the substeps: restitution sweeps of this schedule until no
        bouncing row is off its target by more than ``tolerance`` [m/s] (one sweep for PGS on a
        lone contact, several for the split schedules, as in the solve itself), at most
        ``max_sweeps``; then their impulses join the step's sum. Returns the sweeps run (each
        ends with one read of the largest residual; a step where nothing bounces stops after
        one)."""
        rows = buf.rows
        done = 0
        while done < max_sweeps:
            rows.bounce_residual[None] = 0.0
            self.sweep(buf, awake, contact_rows.RESTITUTION, friction)
            done += 1
            if rows.bounce_residual[None] <= tolerance:
                break
        step_impulses.add_bounces(rows, buf.contacts)
        return done

    # ------------------------------------------------------------------ the fused iteration loop
    def launch(self, settings, arch: str, body_capacity: int, plan) -> str:
        """Which launch runs the iteration loop of a world with buffers for ``body_capacity``
        bodies and a step of ``plan`` (formulation.SweepPlan) (Settings.iteration_launch;
        "per-stage" is also what a profiled world uses). All give bit-identical results."""
        launch = settings.iteration_launch
        if launch == "auto" and arch == "cpu":
            launch = "one" if body_capacity <= ONE_THREAD_BODY_LIMIT else "shared"
        elif launch == "auto":
            launch = "per-substep"
        if launch == "shared" and arch != "cpu":
            launch = "one"  # a GPU block cannot wait for another
        if launch not in self.info.launches:
            launch = _FALLBACK[launch]
        if launch == "per-substep" and not self._unrolls(plan):
            launch = "per-stage"
        return launch

    @staticmethod
    def _unrolls(plan) -> bool:
        """The per-substep launch unrolls ``plan``'s sweeps, up to MAX_STEP_SWEEPS of each kind
        (Settings.step_sweeps); more falls back to a launch per stage."""
        return max(plan.biased, plan.relax) <= MAX_STEP_SWEEPS

    def iterate(self, launch: str, loop: Loop) -> None:
        """The whole iteration loop in one of the fused launches ("one", "shared", "per-substep")."""
        if launch == "one":
            substep.iterate_in_order(*self._loop_args(loop), loop.iterations, loop.sweeps, loop.relax)
        elif launch == "shared":
            crew, members = self.team(loop.buf, loop.iterations, loop.sweeps, loop.relax, loop.ratio)
            team_loop.iterate_shared(crew, *self._loop_args(loop), loop.iterations, loop.sweeps, loop.relax, members)
        elif launch == "per-substep":
            fold = self.folds_warm_start(loop.warm)
            k = loop.iterations
            for i in range(k):
                warm_here, then_warm = int(i == 0 or not fold), int(fold and i < k - 1)
                substep.substep_parallel(*self._loop_args(loop), warm_here, then_warm, i, loop.ratio, loop.sweeps,
                                         loop.relax)
        else:
            raise ValueError(f"iterate: {launch!r} is not a fused launch")

    def team(self, buf, substeps: int, biased: int, relax: int, ratio: int = 0) -> tuple:
        """(the thread team whose counters cover a shared iteration loop of ``substeps``
        substeps with ``biased`` (and up to ``ratio`` more) and ``relax`` sweeps each, its member
        count), with the lane rows its sweeps read allocated in ``buf`` (BufferSet.lane_rows)."""
        buf.lane_rows()
        phases = team_loop.shared_phase_bound(self.visit, substeps, biased, relax, ratio)
        members = team.cpu_threads()
        return team.team_for(phases, members), members

    def _loop_args(self, loop: Loop) -> tuple:
        """The arguments every iteration-loop kernel of substep.py starts with."""
        return (loop.buf, self.kind, self.visit, loop.friction, loop.warm, loop.track, loop.awake, loop.motion, loop.h)
