"""The iteration loop shared by the CPU threads in one launch (``iterate_shared``, the CPU
default; solvers/substep.py has the other launches): the threads form a team (team.py) that
walks every phase of ``substep.iterate_in_order`` in its order, each phase's blocks or bodies
claimed in chunks, each phase waited for at its end. The same bits as the one-thread loop (a
phase's items write only their own outputs), with both cores and one thread-pool wake-up per
step instead of one per phase (~50 us each on the 2-core VM, benchmarks/loop_dispatch.py). Its
sweeps of per-point blocks go eight points at a time, on the vector units (point_lanes.py), and so
do its position updates in a world with the gyroscopic term, eight bodies at a time (pose_lanes.py).
"""

import taichi as ti

from ..awake import body_id, body_total
from ..integrate import GYROSCOPIC, advance_pose, apply_gravity
from ..lanes import LANES
from ..pose_lanes import advance_poses
from ..step_scalars import MATCH_DISTANCE, RELAXATION, WARM_FACTOR
from . import team as tm
from .contact_spring import params_gravity
from .impact_carry import clear_impacts
from .mass_splitting import clamp_folded_carries, gather_body, sweep_block, warm_block
from .point_lanes import lane_block_phase, lane_copy_phase, lanes_apply
from .pgs import MAX_COLORS, solve_manifold
from .rows import BIASED, RELAX
from .set_up import order_blocks, prepare_point
from .step_impulses import add_step_impulse
from .substep import BLOCKS, PGS, PGS_COLORED, folds_warm_start, light_sweeps_now

vec3 = ti.math.vec3



def goes_in_lanes(schedule: int, kind: int, friction: int) -> bool:
    """Whether the team's sweeps go eight points at a time (point_lanes.py): then its lane copy
    can also work out the rows' responses (``iterate_shared_loops``'s ``responds``)."""
    return schedule == BLOCKS and lanes_apply(kind, friction)


def shared_phase_bound(schedule: int, iterations: int, sweeps: int, relax: int, ratio: int = 0) -> int:
    """Most phases ``iterate_shared`` walks (its team needs counters per phase; the Jacobi
    family's substeps may sweep light bodies' blocks ``ratio`` times more and advance the poses
    after them, Settings.ratio_sweeps, and relax once more, Settings.relax_push_speed)."""
    if schedule == PGS_COLORED:
        per_sweep = MAX_COLORS + 1  # every colour, then the overflow colour
        return iterations * ((sweeps + relax) * per_sweep + 4)
    # + 3: the set-up's two phases (_set_up_phases) and the lane copy (point_lanes.py)
    return iterations * (2 * (sweeps + ratio + relax + 1) + 4) + 3


@ti.func
def _block_phase(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, s: ti.template(),
                 rows: ti.template(), c: ti.template(), bodies: ti.template(), kind: ti.template(),
                 mode: ti.template(), friction: ti.template(), then_warm: ti.i32, warm_only: ti.template(),
                 substep: ti.i32 = 0, fast_slot: ti.i32 = 0, listed: ti.template() = False) -> ti.i32:
    """Phase p over all blocks: their warm start, or one sweep (a biased one marks a fast push
    in ``team.fast[fast_slot]``, _team_member); ``listed``: over light bodies' blocks only (an
    extra sweep, light_bodies.py). Returns the next phase."""
    n = s.light_block_count[None] if ti.static(listed) else s.block_count[None]
    lo, hi, j = tm.next_chunk(team, p, n, member, members, 0)
    while lo < hi:
        for idx in range(lo, hi):
            k = s.light_blocks[idx] if ti.static(listed) else idx
            if ti.static(warm_only):
                warm_block(s, rows, c, bodies, kind, friction, k)
            elif sweep_block(s, rows, c, bodies, kind, mode, friction, then_warm, k, substep):
                team.fast[fast_slot] = 1  # a plain store before this member's "finished" increment
        tm.finish(team, p, hi - lo)
        lo, hi, j = tm.next_chunk(team, p, n, member, members, j)
    tm.wait(team, p, n)
    return p + 1


GATHER, GRAVITY, POSE, GATHER_POSE, GATHER_LIGHT = 0, 1, 2, 3, 4
"""What a body phase does to each body: add its slots (and ``dv_extra``), add gravity,
advance its pose, add its slots and then advance its pose, or (a listed body only) add its
light blocks' slots (light_bodies.py)."""


@ti.func
def _body_phase(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, lr: ti.template(),
                s: ti.template(), bodies: ti.template(), awake: ti.template(), motion: ti.template(),
                what: ti.template(), dv_extra: vec3, gravity: vec3, h: ti.f32) -> ti.i32:
    """Phase p over the bodies (or the listed light ones), one ``what`` each. A POSE or GATHER_POSE
    phase of a world with the gyroscopic term claims groups of eight bodies instead, gathered one
    by one and then advanced together (pose_lanes.py). Returns the next phase."""
    grouped = ti.static((what == POSE or what == GATHER_POSE) and motion & GYROSCOPIC)
    n = s.light_body_count[None] if ti.static(what == GATHER_LIGHT) else body_total(bodies, awake)
    items = n
    if ti.static(grouped):
        items = (n + LANES - 1) // LANES
    lo, hi, j = tm.next_chunk(team, p, items, member, members, 0)
    while lo < hi:
        for k in range(lo, hi):
            if ti.static(grouped):
                if ti.static(what == GATHER_POSE):
                    for l in range(ti.min(LANES, n - k * LANES)):
                        gather_body(s, bodies, dv_extra, body_id(awake, k * LANES + l))
                advance_poses(lr.poses, bodies, awake, motion, h, k, n)
            else:
                _body_item(s, bodies, awake, motion, what, dv_extra, gravity, h, k)
        tm.finish(team, p, hi - lo)
        lo, hi, j = tm.next_chunk(team, p, items, member, members, j)
    tm.wait(team, p, items)
    return p + 1


@ti.func
def _body_item(s: ti.template(), bodies: ti.template(), awake: ti.template(), motion: ti.template(),
               what: ti.template(), dv_extra: vec3, gravity: vec3, h: ti.f32, k: ti.i32):
    """Item k of a body phase: what its body (the k-th of the loop, or of the light list) does."""
    i = s.light_bodies[k] if ti.static(what == GATHER_LIGHT) else body_id(awake, k)
    if ti.static(what == GATHER_LIGHT):
        gather_body(s, bodies, dv_extra, i, True)
    if ti.static(what == GATHER or what == GATHER_POSE):
        gather_body(s, bodies, dv_extra, i)
    if ti.static(what == GRAVITY):
        apply_gravity(bodies, gravity, h, i)
    if ti.static(what == POSE or what == GATHER_POSE):
        advance_pose(bodies, motion, h, i)


@ti.func
def _color_phases(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, rows: ti.template(),
                  c: ti.template(), bodies: ti.template(), col: ti.template(), mode: ti.template(),
                  friction: ti.template(), substep: ti.i32) -> ti.i32:
    """One pgs-colored sweep: a phase per colour, then the overflow colour as one item
    (its manifolds may share bodies, so one member solves them all, in order)."""
    for kc in range(col.color_count[None]):
        k0 = col.color_start[kc]
        n = col.color_start[kc + 1] - k0
        lo, hi, j = tm.next_chunk(team, p, n, member, members, 0)
        while lo < hi:
            for idx in range(lo, hi):
                solve_manifold(rows, c, bodies, col.sorted[k0 + idx], mode, friction, substep)
            tm.finish(team, p, hi - lo)
            lo, hi, j = tm.next_chunk(team, p, n, member, members, j)
        tm.wait(team, p, n)
        p += 1
    lo, hi, _ = tm.next_chunk(team, p, 1, member, members, 0)
    if lo < hi:
        for idx in range(col.color_start[MAX_COLORS], col.color_start[MAX_COLORS + 1]):
            solve_manifold(rows, c, bodies, col.sorted[idx], mode, friction, substep)
        tm.finish(team, p, 1)
    tm.wait(team, p, 1)
    return p + 1


@ti.func
def _sweep_phases(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, lr: ti.template(),
                  s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                  motion: ti.template(), col: ti.template(), kind: ti.template(),
                  schedule: ti.template(), mode: ti.template(), friction: ti.template(), then_warm: ti.i32, pose_after: ti.i32, gravity: vec3,
                  h: ti.f32, substep: ti.i32, fast_slot: ti.i32 = 0) -> ti.i32:
    """One sweep of substep ``substep`` (visit_order.visited_point); ``pose_after``: the bodies'
    poses advance right after it (the biased solve's last sweep), fused into the Jacobi family's
    gather. ``fast_slot``: _block_phase."""
    if ti.static(schedule == PGS_COLORED):
        p = _color_phases(team, p, member, members, rows, c, bodies, col, mode, friction, substep)
        if pose_after:
            p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, POSE, vec3(0.0), gravity, h)
    else:
        p = _block_phase(team, p, member, members, s, rows, c, bodies, kind, mode, friction, then_warm, False,
                         substep, fast_slot)
        dv_extra = gravity * h * ti.cast(then_warm, ti.f32)
        if pose_after:
            p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GATHER_POSE, dv_extra, gravity,
                            h)
        else:
            p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GATHER, dv_extra, gravity, h)
    return p


@ti.func
def _carry_phase(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, rows: ti.template(),
                 c: ti.template(), bodies: ti.template(), friction: ti.template()) -> ti.i32:
    """After a relax sweep that carried the next substep's warm start: the listed impact rows'
    carries clamped (mass_splitting.clamp_folded_carries), one item that one member runs in
    order, as a phase of none in a step without an impact row."""
    n = ti.min(rows.carry_count[None], 1)
    lo, hi, _ = tm.next_chunk(team, p, n, member, members, 0)
    if lo < hi:
        clamp_folded_carries(rows, c, bodies, friction)
        tm.finish(team, p, 1)
    tm.wait(team, p, n)
    return p + 1


@ti.func
def _point_phase(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, c: ti.template(),
                 rows: ti.template()) -> ti.i32:
    """The substep's impulses added to the step's, point by point."""
    n = c.count[None]
    lo, hi, j = tm.next_chunk(team, p, n, member, members, 0)
    while lo < hi:
        for q in range(lo, hi):
            add_step_impulse(rows, q)
        tm.finish(team, p, hi - lo)
        lo, hi, j = tm.next_chunk(team, p, n, member, members, j)
    tm.wait(team, p, n)
    return p + 1


@ti.func
def _light_sweeps(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, lr: ti.template(),
                  s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                  motion: ti.template(), kind: ti.template(), friction: ti.template(), gravity: vec3, h: ti.f32,
                  it: ti.i32, extra: ti.i32, fast_slot: ti.i32) -> ti.i32:
    """Substep ``it``'s ``extra`` biased sweeps of light bodies' blocks after the biased sweeps
    (light_sweeps_now), each gathered into its light bodies, then the poses advanced (they were
    held back for these: the last biased sweep's gather did not advance them)."""
    for _e in range(extra):
        p = _block_phase(team, p, member, members, s, rows, c, bodies, kind, BIASED, friction, 0, False, it, fast_slot,
                         True)
        p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GATHER_LIGHT, vec3(0.0), gravity, h)
    if extra > 0:
        p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, POSE, vec3(0.0), gravity, h)
    return p


@ti.func
def _lane_sweeps(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, lr: ti.template(), s: ti.template(),
                 rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                 motion: ti.template(), kind: ti.template(), friction: ti.template(), fold: ti.template(),
                 gravity: vec3, h: ti.f32, it: ti.i32, iterations: ti.i32, sweeps: ti.i32, relax: ti.i32,
                 extra: ti.i32, fast_slot: ti.i32) -> ti.i32:
    """Substep ``it``'s sweeps when they go eight points at a time: the biased ones, the light
    bodies' extra ones, the relax ones (one more after a fast push), each followed by its gather,
    in _team_member's order, but as one loop that reads the kind of sweep at run time, so that
    the lane sweep is compiled once (its compile time: docs/bench.md, "Twelfth pass")."""
    n_relax = relax
    k = 0
    while k < sweeps + n_relax or k == sweeps:
        if k == sweeps:  # the biased sweeps are done
            p = _light_sweeps(team, p, member, members, lr, s, rows, c, bodies, awake, motion, kind, friction, gravity,
                              h, it, extra, fast_slot)
            n_relax = relax + ti.atomic_add(team.fast[fast_slot], 0)  # the same for every member
        if k < sweeps + n_relax:
            biased = 1 if k < sweeps else 0
            then_warm = 0
            if ti.static(fold):
                then_warm = 1 if biased == 0 and it < iterations - 1 and k - sweeps == n_relax - 1 else 0
            p = lane_block_phase(team, p, member, members, lr, s, rows, c, bodies, friction, biased, then_warm,
                                  fast_slot)
            dv_extra = gravity * h * ti.cast(then_warm, ti.f32)
            if biased * int(k == sweeps - 1 and extra == 0):  # the poses advance after the last biased sweep
                p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GATHER_POSE, dv_extra, gravity,
                                h)
            else:
                p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GATHER, dv_extra, gravity, h)
        k += 1
    return p


@ti.func
def _set_up_phases(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, b: ti.template(),
                   kind: ti.template(), mode: ti.template()) -> ti.i32:
    """The step's set-up (set_up.py, as step_kernels.prepare_step_loops runs it, the responses
    left to the lane copy) as two phases of the team, so that it needs no loop of its own: each point's rows and warm-start
    match, claimed in chunks as the sweeps are (a point writes only its own rows); then the impact
    rows' list and the block adjacency, one item that one member runs in order, as the launching
    thread ran them (on the CPU their loops are serial: backend.serialize_light_loops). The same
    loops in the same order: the same bits. Returns the next phase."""
    f = ti.static(b.scalars.f)
    n = b.contacts.count[None]
    lo, hi, j = tm.next_chunk(team, p, n, member, members, 0)
    while lo < hi:
        for q in range(lo, hi):
            prepare_point(b, q, f[MATCH_DISTANCE], f[WARM_FACTOR], False)
        tm.finish(team, p, hi - lo)
        lo, hi, j = tm.next_chunk(team, p, n, member, members, j)
    tm.wait(team, p, n)
    p += 1
    lo, hi, _ = tm.next_chunk(team, p, 1, member, members, 0)
    if lo < hi:
        order_blocks(b, b.blocks, kind, mode, f[RELAXATION])
        tm.finish(team, p, 1)
    tm.wait(team, p, 1)
    return p + 1


@ti.func
def _team_member(team: ti.template(), member: ti.i32, members: ti.i32, lr: ti.template(), s: ti.template(),
                 rows: ti.template(),
                 c: ti.template(), bodies: ti.template(), col: ti.template(), kind: ti.template(),
                 schedule: ti.template(), friction: ti.template(), warm: ti.template(), track: ti.template(),
                 awake: ti.template(), motion: ti.template(), gravity: vec3, h: ti.f32, iterations: ti.i32,
                 sweeps: ti.i32, relax: ti.i32, responds: ti.template(), split: ti.template(), b: ti.template(),
                 mode: ti.template(), sets_up: ti.template()):
    """What one thread runs: every phase of ``iterate_in_order``, in its order (with ``sets_up``,
    the step's set-up first)."""
    fold = ti.static(folds_warm_start(schedule, warm))
    grouped = ti.static(goes_in_lanes(schedule, kind, friction))
    p = 0
    if ti.static(sets_up):
        p = _set_up_phases(team, p, member, members, b, kind, mode)
    if ti.static(grouped):
        p = lane_copy_phase(team, p, member, members, lr, s, rows, c, bodies, responds, split, friction)
    for it in range(iterations):
        first = 1
        if ti.static(fold):
            first = 1 if it == 0 else 0
        if first:
            if ti.static(warm):
                p = _block_phase(team, p, member, members, s, rows, c, bodies, kind, BIASED, friction, 0, True)
                p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GATHER, gravity * h,
                                gravity, h)
            else:
                p = _body_phase(team, p, member, members, lr, s, bodies, awake, motion, GRAVITY, vec3(0.0),
                                gravity, h)
        fast_slot = p  # this substep's biased phases mark a fast push here; read once they are all done
        extra = light_sweeps_now(s, schedule)  # the same for every member: set before the loop
        if ti.static(grouped):
            p = _lane_sweeps(team, p, member, members, lr, s, rows, c, bodies, awake, motion, kind, friction, fold,
                             gravity, h, it, iterations, sweeps, relax, extra, fast_slot)
        else:
            for sb in range(sweeps):
                p = _sweep_phases(team, p, member, members, lr, s, rows, c, bodies, awake, motion, col, kind, schedule,
                                  BIASED, friction, 0, int(sb == sweeps - 1 and extra == 0), gravity, h, it, fast_slot)
            if ti.static(schedule == BLOCKS):
                p = _light_sweeps(team, p, member, members, lr, s, rows, c, bodies, awake, motion, kind, friction,
                                  gravity, h, it, extra, fast_slot)
            n_relax = relax
            if ti.static(schedule == BLOCKS):
                # the same for every member: never reset in a loop
                n_relax = relax + ti.atomic_add(team.fast[fast_slot], 0)
            for sr in range(n_relax):
                then_warm = 0
                if ti.static(fold):
                    then_warm = 1 if it < iterations - 1 and sr == n_relax - 1 else 0
                p = _sweep_phases(team, p, member, members, lr, s, rows, c, bodies, awake, motion, col, kind, schedule,
                                  RELAX, friction, then_warm, 0, gravity, h, it)
        if ti.static(fold):
            if it < iterations - 1:
                p = _carry_phase(team, p, member, members, rows, c, bodies, friction)
        if ti.static(track):
            p = _point_phase(team, p, member, members, c, rows)


@ti.func
def iterate_shared_loops(team: ti.template(), b: ti.template(), kind: ti.template(), schedule: ti.template(),
                         friction: ti.template(), warm: ti.template(), track: ti.template(), awake: ti.template(),
                         motion: ti.template(), h: ti.f32, iterations: ti.i32, sweeps: ti.i32, relax: ti.i32,
                         members: ti.i32, responds: ti.template() = False, split: ti.template() = False,
                         mode: ti.template() = 0, sets_up: ti.template() = False):
    """All ``iterations`` substeps of ``h``, shared by ``members`` threads, after clearing every
    counter of the team (sized for at least ``shared_phase_bound`` x ``members``, Schedule.team):
    a serial loop, then one top-level loop that starts a member per thread. ``responds`` (only
    where ``goes_in_lanes``): the rows' responses (rows.respond_row, ``split`` its switch) are
    worked out in the lane copy, on every thread, instead of by the step's set-up. ``sets_up``
    (with ``responds``): the set-up itself is the team's first phases (``_set_up_phases``, ``mode``
    the schedule's merge), so the step needs no loop besides the team's before its store."""
    ti.static_assert(schedule != PGS, "serial PGS has nothing to share")
    ti.static_assert(not responds or goes_in_lanes(schedule, kind, friction), "only the lane copy responds")
    ti.static_assert(not sets_up or responds, "the team sets up only where its lane copy responds")
    s, rows, c, bodies, col = b.blocks, b.rows, b.contacts, b.bodies, b.coloring
    if ti.static(sets_up):
        clear_impacts(rows)  # before any row is prepared (impact_carry.note_impact)
    gravity = params_gravity(rows)  # the step's gravity rides in rows.params (contact_spring.row_params)
    tm.reset_loop(team, ti.static(team.claimed.shape[0]))
    for i in range(members * tm.TASK_ITEMS):
        if i % tm.TASK_ITEMS == 0:
            _team_member(team, i // tm.TASK_ITEMS, members, b.lanes, s, rows, c, bodies, col, kind, schedule, friction,
                         warm, track, awake, motion, gravity, h, iterations, sweeps, relax, responds, split, b, mode,
                         sets_up)


@ti.kernel
def iterate_shared(team: ti.template(), b: ti.template(), kind: ti.template(), schedule: ti.template(),
                   friction: ti.template(), warm: ti.template(), track: ti.template(), awake: ti.template(),
                   motion: ti.template(), h: ti.f32, iterations: ti.i32, sweeps: ti.i32, relax: ti.i32,
                   members: ti.i32):
    """All ``iterations`` substeps of ``h`` in one launch, shared by ``members`` threads
    (``iterate_shared_loops``; ``team``, ``members``: Schedule.team)."""
    iterate_shared_loops(team, b, kind, schedule, friction, warm, track, awake, motion, h, iterations, sweeps, relax,
                         members)
