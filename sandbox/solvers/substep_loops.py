"""The Jacobi family's substep as a GPU launches it: loops, and nothing between them.

Every top-level loop of a Taichi kernel is its own task, and so is every run of statements
between two loops: a loop range read at run time (``range(count[None])``), a value computed for
the loops after it, even the copies of a ``ti.func``'s value arguments. On the CPU such a serial
task is a few instructions on the launching thread; on a GPU it is a single-thread launch of its
own, 6-7 us on an H200, and the substep launched 9 of them beside its 9 loops (docs/bench.md,
"The third CUDA run"). Here the substep's loops read every value themselves (gravity, the warm
start switches, the fast-push flag), run to their buffers' capacities under CUDA's loop shapes
(``backend.capacity_ranges``: each thread compares its index with the count), and take no value
arguments at the top level (``ti.template()``: passed as expressions, evaluated inside the loops).
The warm start's gather also clears the fast-push flag, and the last biased sweep's gather
advances the poses (each body's pose reads its own velocities only): 8 tasks per substep instead
of 18 (2 more per extra sweep of either kind, Settings.step_sweeps), the same arithmetic in
the same order, so the same bits (tests/test_dispatch.py).
"""

import taichi as ti

from ..awake import body_id, body_total
from ..backend import capacity_ranges
from ..integrate import advance_pose, apply_gravity
from .contact_spring import params_gravity
from .mass_splitting import clamp_folded_carries, gather_body, sweep_block, warm_block
from .rows import BIASED, RELAX
from .step_impulses import add_step_impulse


@ti.func
def _upto(count: ti.template(), capacity: ti.template(), at_least_one: ti.template() = False):
    """A top-level loop's range: the buffer's ``capacity``, a constant, under CUDA's loop
    shapes; else ``count`` (at least 1 for a loop that must run once). Its arguments are
    templates, so the call adds no statement before the loop."""
    if ti.static(capacity_ranges()):
        return capacity
    elif ti.static(at_least_one):
        return ti.max(count, 1)
    else:
        return count


@ti.func
def _carry_after(rows: ti.template(), then_warm: ti.template(), last: ti.template()) -> ti.i32:
    """1: this relax sweep carries the next substep's gravity and warm start (the last of the
    substep's relax sweeps, without a fast push: that earns one more, which carries it instead)."""
    carry = 0
    if ti.static(last):
        carry = then_warm * (1 - rows.fast_push[None])
    return carry


@ti.func
def jacobi_substep_loops(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                         awake: ti.template(), kind: ti.template(), friction: ti.template(), warm: ti.template(),
                         fold: ti.template(), track: ti.template(), motion: ti.template(), h: ti.template(),
                         first: ti.template(), then_warm: ti.template(), substep: ti.template(),
                         ratio: ti.template(), biased: ti.template(), relax: ti.template()):
    """``substep.substep_parallel`` for the Jacobi family (its arguments, as expressions; a range
    is written in each loop's header: a name assigned here would be a statement). ``biased``,
    ``relax``: the substep's sweeps of each kind (formulation.SweepPlan; more than one at few
    iterations, Settings.step_sweeps), unrolled as ``ratio`` is. ``ratio``: the
    extra sweeps of light bodies' blocks (Settings.ratio_sweeps, formulation.SweepPlan.ratio),
    unrolled: 2 ``ratio`` + 1 loops more, which run empty in a step without a light body (a world
    whose masses never differ that much compiles them out under CUDA's loop shapes: ``ratio`` 0,
    effects.py). This
    step's count ``s.light_sweeps`` is 0 or ``ratio`` (written from the same plan's row
    parameters, light_bodies.list_light_body) and decides whether they run and where the poses
    advance."""
    if ti.static(warm):
        for k in range(_upto(s.block_count[None], s.block_capacity)):
            if k < s.block_count[None] * first:
                warm_block(s, rows, c, bodies, kind, friction, k)
    for k in range(_upto(body_total(bodies, awake), bodies.capacity, at_least_one=True)):
        if k == 0:
            rows.fast_push[None] = 0  # no block of the warm start reads it
        if k < body_total(bodies, awake) * first:
            if ti.static(warm):
                gather_body(s, bodies, params_gravity(rows) * h, body_id(awake, k))
            else:
                apply_gravity(bodies, params_gravity(rows), h, body_id(awake, k))
    for sweep in ti.static(range(biased)):  # the poses advance after the last (or after the extra sweeps)
        for k in range(_upto(s.block_count[None], s.block_capacity)):
            if k < s.block_count[None]:
                if sweep_block(s, rows, c, bodies, kind, BIASED, friction, 0, k, substep):
                    rows.fast_push[None] = 1
        for k in range(_upto(body_total(bodies, awake), bodies.capacity)):
            if k < body_total(bodies, awake):
                i = body_id(awake, k)
                gather_body(s, bodies, params_gravity(rows) * h * ti.cast(0, ti.f32), i)
                if ti.static(sweep == biased - 1):
                    if s.light_sweeps[None] == 0:
                        advance_pose(bodies, motion, h, i)
    for e in ti.static(range(ratio)):  # light bodies' blocks, listed (light_bodies.py)
        for j in range(_upto(s.light_block_count[None], s.block_capacity)):
            if j < s.light_block_count[None] * ti.cast(s.light_sweeps[None] > e, ti.i32):
                if sweep_block(s, rows, c, bodies, kind, BIASED, friction, 0, s.light_blocks[j], substep):
                    rows.fast_push[None] = 1
        for j in range(_upto(s.light_body_count[None], s.body_capacity)):
            if j < s.light_body_count[None] * ti.cast(s.light_sweeps[None] > e, ti.i32):
                gather_body(s, bodies, ti.math.vec3(0.0), s.light_bodies[j], True)
    if ti.static(ratio > 0):
        for k in range(_upto(body_total(bodies, awake), bodies.capacity)):
            if k < body_total(bodies, awake) * ti.cast(s.light_sweeps[None] > 0, ti.i32):
                advance_pose(bodies, motion, h, body_id(awake, k))
    # the relax sweeps, the last carrying the next warm start (a fast push: one more, which then
    # carries it); no relax block writes the flag, so every thread reads the biased and extra sweeps'
    for sweep in ti.static(range(relax)):
        for k in range(_upto(s.block_count[None], s.block_capacity)):
            if k < s.block_count[None]:
                sweep_block(s, rows, c, bodies, kind, RELAX, friction,
                            _carry_after(rows, then_warm, sweep == relax - 1), k, substep)
        for k in range(_upto(body_total(bodies, awake), bodies.capacity)):
            if k < body_total(bodies, awake):
                carry = _carry_after(rows, then_warm, sweep == relax - 1)
                gather_body(s, bodies, params_gravity(rows) * h * ti.cast(carry, ti.f32), body_id(awake, k))
    for k in range(_upto(s.block_count[None], s.block_capacity)):
        if k < s.block_count[None] * rows.fast_push[None]:
            sweep_block(s, rows, c, bodies, kind, RELAX, friction, then_warm, k, substep)
    for k in range(_upto(body_total(bodies, awake), bodies.capacity)):
        if k < body_total(bodies, awake) * rows.fast_push[None]:
            gather_body(s, bodies, params_gravity(rows) * h * ti.cast(then_warm, ti.f32), body_id(awake, k))
    if ti.static(fold):  # the impact rows' carries clamped after the carrying sweep's merge, in order
        for _ in range(1):
            if then_warm:
                clamp_folded_carries(rows, c, bodies, friction)
    if ti.static(track):
        for q in range(_upto(c.count[None], c.capacity)):
            if q < c.count[None]:
                add_step_impulse(rows, q)
