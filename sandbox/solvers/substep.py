"""The iteration loop (Box2D v3's soft step, solvers/rows.py) in as few kernel launches as
the method allows.

One iteration is a substep: gravity, warm start, biased sweep(s), position update, relax
sweep(s). Run stage by stage that is 5+ launches per iteration, and on a small scene the
launches, not the arithmetic, set the cost (apis.md 4.5: ~20 us of Python and runtime per
launch; measured here ~60 % of a 1000-box pile's step). Every phase is written once as a
``ti.func`` holding its loop(s) (integrate.py, mass_splitting.py, pgs.py); this module only chains
them, in two ways:

* ``iterate_in_order``: the whole iteration loop in ONE launch. Its outer loop over the
  iterations is serialized, and Taichi runs every loop nested in it in order on one thread
  (only a kernel's outermost loops are parallel). For the Jacobi family the result is bit
  for bit that of the parallel launches: a block reads only the velocities from before the
  sweep, writes only its own slots and rows (and, a biased one with a fast push, the same 1
  into a shared flag), and each body sums its slots in a fixed order; for
  ``pgs-colored`` the manifolds of one colour share no dynamic body. What is lost is the
  thread parallelism inside a sweep.
* ``substep_parallel``: ONE launch per substep whose top-level loops (each phase's loops)
  run one after another, each in parallel, as on a GPU. ``pgs-colored`` keeps its launch
  per colour (a colour count known only on the device cannot be unrolled into top-level
  loops), so it is not offered here.

* ``iterate_shared`` (team_loop.py): the whole loop in ONE launch as ``iterate_in_order``, but every
  CPU thread works on it: the threads form a team (solvers/team.py) that walks the same
  phases, sharing each phase's blocks or bodies and waiting at its end. The same bits
  again, with both cores and without a thread-pool dispatch per phase (~50 us each on
  the 2-core VM, benchmarks/loop_dispatch.py): the CPU default. Its sweeps of per-point
  blocks go eight points at a time, on the vector units (point_lanes.py): the same bits.

``Schedule.launch`` (solvers/schedule.py) picks one from ``Settings.iteration_launch``
and what the solver's description allows; ``step.py`` keeps the stage-by-stage kernels
for the profiler (one timer per stage) and for residual recording (a read per sweep).
"""

import taichi as ti

from ..integrate import gravity_loop, positions_loop
from .contact_spring import params_gravity
from .mass_splitting import clamp_folded_carries, sweep_blocks, sweep_light_blocks, warm_start_blocks
from .pgs import colored_sweep_in_order, pgs_sweep
from .rows import BIASED, RELAX
from .step_impulses import add_step_impulses_loop
from .substep_loops import jacobi_substep_loops

vec3 = ti.math.vec3

PGS, PGS_COLORED, BLOCKS = 0, 1, 2
"""How a schedule visits its rows: serial PGS, PGS colour by colour, or blocks with slots."""


@ti.func
def _sweep(schedule: ti.template(), s: ti.template(), rows: ti.template(), c: ti.template(),
           bodies: ti.template(), awake: ti.template(), col: ti.template(), kind: ti.template(), mode: ti.template(),
           friction: ti.template(), then_warm: ti.i32, gravity: vec3, h: ti.f32, substep: ti.i32):
    if ti.static(schedule == PGS):
        pgs_sweep(rows, c, bodies, mode, friction, substep)
    elif ti.static(schedule == PGS_COLORED):
        colored_sweep_in_order(rows, c, bodies, col, mode, friction, substep)
    else:
        sweep_blocks(s, rows, c, bodies, awake, kind, mode, friction, then_warm, gravity, h, substep)


@ti.func
def _start_substep(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                   awake: ti.template(), kind: ti.template(), warm: ti.template(), friction: ti.template(),
                   gravity: vec3, h: ti.f32, active: ti.i32):
    """Gravity and warm start of a substep (``active`` = 0 skips both: the Jacobi family's
    later substeps get them from the previous relax sweep, mass_splitting.sweep_blocks, whose
    impact rows' carries are clamped after its merge, mass_splitting.clamp_folded_carries)."""
    if ti.static(warm):
        warm_start_blocks(s, rows, c, bodies, awake, kind, friction, gravity, h, active)
    else:
        gravity_loop(bodies, awake, gravity, h, active)


def folds_warm_start(schedule: int, warm: bool) -> bool:
    """The Jacobi family carries gravity and warm start on the last relax sweep (not PGS:
    there the velocities a later manifold sees would change)."""
    return warm and schedule == BLOCKS



@ti.func
def light_sweeps_now(s: ti.template(), schedule: ti.template()) -> ti.i32:
    """This step's extra biased sweeps of light bodies' blocks (Settings.ratio_sweeps, counted by
    block_adjacency.build_adjacency; 0 in a step without a light body): the Jacobi family's only."""
    extra = 0
    if ti.static(schedule == BLOCKS):
        extra = s.light_sweeps[None]
    return extra


@ti.func
def iterate_in_order_loops(b: ti.template(), kind: ti.template(), schedule: ti.template(), friction: ti.template(),
                           warm: ti.template(), track: ti.template(), awake: ti.template(), motion: ti.template(),
                           h: ti.f32, iterations: ti.i32, sweeps: ti.i32, relax: ti.i32):
    """All ``iterations`` substeps of ``h``, everything in order on one thread: ``sweeps`` biased
    and ``relax`` relax sweeps each (formulation.sweep_plan; under the Jacobi family the extra
    sweeps of light bodies' blocks after the biased ones, light_sweeps_now, and one relax sweep
    more after a fast push, Settings.relax_push_speed). ``track``: each substep's impulses
    are added to the step's (``rows.lam_step``). ``b``: the world's BufferSet (one template
    argument instead of six: step_kernels.py says why)."""
    s, rows, c, bodies, col = b.blocks, b.rows, b.contacts, b.bodies, b.coloring
    gravity = params_gravity(rows)  # the step's gravity rides in rows.params (contact_spring.row_params)
    fold = ti.static(folds_warm_start(schedule, warm))
    ti.loop_config(serialize=True)
    for it in range(iterations):
        first = 1
        if ti.static(fold):
            first = 1 if it == 0 else 0
        _start_substep(s, rows, c, bodies, awake, kind, warm, friction, gravity, h, first)
        if ti.static(schedule == BLOCKS):
            rows.fast_push[None] = 0
        for _sb in range(sweeps):
            _sweep(schedule, s, rows, c, bodies, awake, col, kind, BIASED, friction, 0, gravity, h, it)
        if ti.static(schedule == BLOCKS):
            for _e in range(light_sweeps_now(s, schedule)):
                sweep_light_blocks(s, rows, c, bodies, kind, friction, it)
        positions_loop(bodies, awake, motion, h)
        n_relax = relax
        if ti.static(schedule == BLOCKS):
            n_relax = relax + rows.fast_push[None]  # a fast push: one more relax sweep (Settings.relax_push_speed)
        for sr in range(n_relax):
            then_warm = 0
            if ti.static(fold):
                then_warm = 1 if it < iterations - 1 and sr == n_relax - 1 else 0
            _sweep(schedule, s, rows, c, bodies, awake, col, kind, RELAX, friction, then_warm, gravity, h, it)
        if ti.static(fold):
            if it < iterations - 1:
                clamp_folded_carries(rows, c, bodies, friction)
        if ti.static(track):
            add_step_impulses_loop(rows, c)


@ti.kernel
def iterate_in_order(b: ti.template(), kind: ti.template(), schedule: ti.template(), friction: ti.template(),
                     warm: ti.template(), track: ti.template(), awake: ti.template(), motion: ti.template(),
                     h: ti.f32, iterations: ti.i32, sweeps: ti.i32, relax: ti.i32):
    """The iteration loop in one launch (``iterate_in_order_loops``)."""
    iterate_in_order_loops(b, kind, schedule, friction, warm, track, awake, motion, h, iterations, sweeps, relax)


@ti.kernel
def substep_parallel(b: ti.template(), kind: ti.template(), schedule: ti.template(), friction: ti.template(),
                     warm: ti.template(), track: ti.template(), awake: ti.template(), motion: ti.template(),
                     h: ti.f32, first: ti.i32, then_warm: ti.i32, substep: ti.i32, ratio: ti.template(),
                     biased: ti.template(), relax: ti.template()):
    """One substep of ``h``: ``biased`` biased and ``relax`` relax sweeps (formulation.SweepPlan,
    unrolled), under the Jacobi family up to ``ratio`` extra biased sweeps of light bodies' blocks
    (Settings.ratio_sweeps) and a second relax sweep after a fast push (Settings.relax_push_speed;
    their loops run zero times otherwise), every phase's loops parallel, in one launch. ``first``:
    this substep does its own gravity and warm start; ``then_warm``: its last relax sweep does the
    next one's (both 1 / 0 decided by ``Schedule.iterate`` with ``folds_warm_start``; after a
    carrying sweep the impact rows' carries are clamped, mass_splitting.clamp_folded_carries; the
    PGS solvers' sweeps ignore it). ``substep``: its index in the step (visit_order.visited_point)."""
    ti.static_assert(schedule != PGS_COLORED, "pgs-colored launches once per colour")
    s, rows, c, bodies, col = b.blocks, b.rows, b.contacts, b.bodies, b.coloring
    if ti.static(schedule == BLOCKS):  # loops and nothing between them (substep_loops.py says why)
        fold = ti.static(folds_warm_start(schedule, warm))
        jacobi_substep_loops(s, rows, c, bodies, awake, kind, friction, warm, fold, track, motion, h, first, then_warm,
                             substep, ratio, biased, relax)
    else:
        gravity = params_gravity(rows)  # the step's gravity rides in rows.params (contact_spring.row_params)
        _start_substep(s, rows, c, bodies, awake, kind, warm, friction, gravity, h, first)
        for _ in ti.static(range(biased)):
            _sweep(schedule, s, rows, c, bodies, awake, col, kind, BIASED, friction, 0, gravity, h, substep)
        positions_loop(bodies, awake, motion, h)
        for _ in ti.static(range(relax)):
            _sweep(schedule, s, rows, c, bodies, awake, col, kind, RELAX, friction, then_warm, gravity, h, substep)
        if ti.static(track):
            add_step_impulses_loop(rows, c)
