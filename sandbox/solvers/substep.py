"""The iteration loop (Box2D v3's soft step, solvers/rows.py) in as few kernel launches as
the method allows.

One iteration is a substep: gravity, warm start, biased sweep(s), position update, relax
sweep(s). Run stage by stage that is 5+ launches per iteration, and on a small scene the
launches, not the arithmetic, set the cost (apis.md 4.5: ~20 us of Python and runtime per
launch; measured here ~60 % of a 1000-box pile's step). Every phase is written once as a
``ti.func`` holding its loop(s) (integrate.py, blocks.py, pgs.py); this module only chains
them, in two ways:

* ``iterate_in_order``: the whole iteration loop in ONE launch. Its outer loop over the
  iterations is serialized, and Taichi runs every loop nested in it in order on one thread
  (only a kernel's outermost loops are parallel). For the Jacobi family the result is bit
  for bit that of the parallel launches: a block reads only the velocities from before the
  sweep, writes only its own slots, and each body sums its slots in a fixed order; for
  ``pgs-colored`` the manifolds of one colour share no dynamic body. What is lost is the
  thread parallelism inside a sweep, which on the shared 2-core machine measured as nothing
  (1 vs 2 threads within noise on the 1000-box pile) while the launch overhead is real.
* ``substep_parallel``: ONE launch per substep whose top-level loops (each phase's loops)
  run one after another, each in parallel, as on a GPU. ``pgs-colored`` keeps its launch
  per colour (a colour count known only on the device cannot be unrolled into top-level
  loops), so it is not offered here.

``World`` picks one (``Settings.iteration_launch``) and keeps the stage-by-stage kernels
for the profiler (one timer per stage) and for residual recording (a read per sweep).
"""

import taichi as ti

from ..integrate import gravity_loop, positions_loop
from .blocks import sweep_blocks, warm_start_blocks
from .pgs import colored_sweep_in_order, pgs_sweep
from .rows import BIASED, RELAX

vec3 = ti.math.vec3

PGS, PGS_COLORED, BLOCKS = 0, 1, 2
"""How a schedule visits its rows: serial PGS, PGS colour by colour, or blocks with slots."""


@ti.func
def _sweep(schedule: ti.template(), s: ti.template(), rows: ti.template(), c: ti.template(),
           bodies: ti.template(), col: ti.template(), kind: ti.template(), mode: ti.template(),
           friction: ti.template(), then_warm: ti.i32, gravity: vec3, h: ti.f32):
    if ti.static(schedule == PGS):
        pgs_sweep(rows, c, bodies, mode, friction)
    elif ti.static(schedule == PGS_COLORED):
        colored_sweep_in_order(rows, c, bodies, col, mode, friction)
    else:
        sweep_blocks(s, rows, c, bodies, kind, mode, friction, then_warm, gravity, h)


@ti.func
def _start_substep(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                   kind: ti.template(), warm: ti.template(), gravity: vec3, h: ti.f32, active: ti.i32):
    """Gravity and warm start of a substep (``active`` = 0 skips both: the Jacobi family's
    later substeps get them from the previous relax sweep, blocks.sweep_blocks)."""
    if ti.static(warm):
        warm_start_blocks(s, rows, c, bodies, kind, gravity, h, active)
    else:
        gravity_loop(bodies, gravity, h, active)


def folds_warm_start(schedule: int, warm: bool) -> bool:
    """The Jacobi family carries gravity and warm start on the last relax sweep (not PGS:
    there the velocities a later manifold sees would change)."""
    return warm and schedule == BLOCKS


@ti.kernel
def iterate_in_order(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                     col: ti.template(), err: ti.template(), kind: ti.template(), schedule: ti.template(),
                     friction: ti.template(), warm: ti.template(), gravity: vec3, h: ti.f32, iterations: ti.i32,
                     sweeps: ti.i32):
    """All ``iterations`` substeps of ``h`` in one launch, everything in order on one thread."""
    fold = ti.static(folds_warm_start(schedule, warm))
    ti.loop_config(serialize=True)
    for it in range(iterations):
        first = 1
        if ti.static(fold):
            first = 1 if it == 0 else 0
        _start_substep(s, rows, c, bodies, kind, warm, gravity, h, first)
        for _sb in range(sweeps):
            _sweep(schedule, s, rows, c, bodies, col, kind, BIASED, friction, 0, gravity, h)
        positions_loop(bodies, h, err)
        for sr in range(sweeps):
            then_warm = 0
            if ti.static(fold):
                then_warm = 1 if it < iterations - 1 and sr == sweeps - 1 else 0
            _sweep(schedule, s, rows, c, bodies, col, kind, RELAX, friction, then_warm, gravity, h)


@ti.kernel
def substep_parallel(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                     col: ti.template(), err: ti.template(), kind: ti.template(), schedule: ti.template(),
                     friction: ti.template(), warm: ti.template(), gravity: vec3, h: ti.f32, first: ti.i32,
                     then_warm: ti.i32):
    """One substep of ``h`` with one sweep each, every phase's loops parallel, in one launch.
    ``first``: this substep does its own gravity and warm start; ``then_warm``: its relax
    sweep does the next one's (both 1 / 0 decided by ``World`` with ``folds_warm_start``)."""
    ti.static_assert(schedule != PGS_COLORED, "pgs-colored launches once per colour")
    _start_substep(s, rows, c, bodies, kind, warm, gravity, h, first)
    _sweep(schedule, s, rows, c, bodies, col, kind, BIASED, friction, 0, gravity, h)
    positions_loop(bodies, h, err)
    _sweep(schedule, s, rows, c, bodies, col, kind, RELAX, friction, then_warm, gravity, h)
