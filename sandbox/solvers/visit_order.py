"""The order in which a Gauss-Seidel pass visits a manifold's points (serial and coloured PGS,
and block mass splitting's in-place block solve; per-point schedules have one point per block).

The first point a pass reaches takes more of the substep's load than the others, so one fixed
order leaves the bodies the same small turn every pass; turning the starting point every
substep cancels it (docs/method-notes.md, "A column's sway: the order inside a manifold").
"""

import taichi as ti


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
