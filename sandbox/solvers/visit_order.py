"""How a Gauss-Seidel sweep solves a manifold's points (serial and coloured PGS, and block mass
splitting's in-place block solve; per-point schedules have one point per block): in which order,
and how many times.

The first point a pass reaches takes more of the substep's load than the others, so one fixed
order leaves the bodies the same small turn every pass; turning the starting point every
substep cancels it (docs/method-notes.md, "A column's sway: the order inside a manifold").

One pass leaves a manifold unconverged, and at an impact that is seen: the corners of a tall
box's foot are 0.2 m apart under 1 m of body, so their rows are nearly dependent, and the corner
solved first stops the impact alone and turns it into spin, which the warm start carries on (a
0.2 x 0.2 x 1 m box landing upright at 10 m/s left the ground at 1.06 m/s and tipped over). A
block with an impact row is therefore passed over until its normal impulses settle
(``gauss_seidel_block``); every other block gets its one pass, as before.
"""

import taichi as ti

from .impact_carry import is_impact
from .rows import RESTITUTION, solve_point

IMPACT_PASSES = 16
"""Most passes a block with an impact row gets in one sweep. Measured on the tall box above
(serial PGS, 10 iterations, rebound from 10 m/s): 1.06 m/s with one pass, 0.16 with 2, 0.12 with
4, 0.07 with 8, 0.02 with 16 (docs/method-notes.md)."""
IMPACT_TOLERANCE = 1e-3
"""[1] A block's passes stop when no normal impulse of it changed by more than this fraction of
their sum in the last pass."""


@ti.func
def visited_point(start: ti.i32, count: ti.i32, substep: ti.i32, i: ti.i32) -> ti.i32:
    """The i-th point a Gauss-Seidel pass in substep ``substep`` of a step visits of the manifold
    whose points are ``start`` .. ``start + count - 1``: it starts at the next point round the
    manifold every substep, so every corner of a face goes first equally often (module
    docstring). Measured against the alternatives: with one fixed order a straight column of
    boxes walked sideways (serial PGS 22-26 mm at 8-30 iterations, block mass splitting 29 mm at
    8); reversing the order on alternate sweeps starts on the same side and toppled the friction
    arch. ``substep`` is a value, not a field: the CPU team's late members walk phases others have
    finished, and would race on a shared one."""
    j = i + substep % count
    if j >= count:
        j -= count
    return start + j


@ti.func
def gauss_seidel_block(rows: ti.template(), c: ti.template(), bodies: ti.template(), start: ti.i32, count: ti.i32,
                       substep: ti.i32, va: ti.math.vec3, wa: ti.math.vec3, vb: ti.math.vec3, wb: ti.math.vec3,
                       mode: ti.template(), friction: ti.template()):
    """The points ``start`` .. ``start + count - 1`` solved one after another on the velocities
    (va, wa, vb, wb), in ``visited_point``'s order: one pass, or, for a block with an impact row
    (impact_carry.is_impact), passes until its normal impulses settle (module docstring)."""
    passes = 1
    if ti.static(mode != RESTITUTION):
        if rows.impacts[None]:  # a step without impact rows reads nothing more
            for i in range(count):
                if is_impact(rows, c, start + i):
                    passes = IMPACT_PASSES
    p = 0
    while p < passes:
        change = 0.0
        total = 0.0
        for i in range(count):
            q = visited_point(start, count, substep, i)
            before = rows.lam[q][0]
            va, wa, vb, wb = solve_point(rows, c, bodies, q, va, wa, vb, wb, mode, friction)
            change = ti.max(change, ti.abs(rows.lam[q][0] - before))
            total += rows.lam[q][0]
        p += 1
        if change <= IMPACT_TOLERANCE * total:
            p = passes
    return va, wa, vb, wb
