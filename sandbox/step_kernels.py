"""The once-per-step stages fused into three kernel launches (CPU launch overhead, issue #3),
and for a world with nothing to do on the host mid-step, the solve in one.

A step's set-up is a dozen small kernels (save state, world inertia, grid, pairs,
narrowphase, rows, warm-start matching, adjacency, responses, finite check, contact
store), each a launch of ~50 us of Python and runtime, and each parallel loop waits for
both worker threads. Every stage's loops are written once as a ``ti.func`` (``*_loops``,
next to its kernel); here they are chained at the top level of one kernel each, so every
loop stays a parallel loop run in the same order as the separate launches: the same bits.
``step.py`` uses these when the profiler is off (the profiler times the separate kernels);
``build.upload`` uses ``after_upload`` once per upload.
Each takes the world's ``BufferSet`` as one template argument ``b`` rather than its parts:
Taichi works out a launch's kernel instance from its template arguments in Python, ~6
attribute look-ups per data-oriented argument, which came to a fifth of a small scene's step;
the step's kernels also skip that work when called again with the same arguments
(repeat_launch.py).
"""

from dataclasses import dataclass

import taichi as ti

from .awake import EVERY
from .bodies import save_good_state_loops, update_world_inertia_loops
from .broadphase import build_dynamic_grid_loops, compute_all_aabbs_loops
from .contacts import clear_contacts_loops, collide_pairs_loops
from .integrate import check_bodies_loops, clear_error_flags
from .manifold_cache import clear_cache_loops
from .pair_search import find_pairs_loops
from .persistence import clear_history_loops, store_contacts_loops
from .repeat_launch import repeat_launch
from .sleep import rest_and_label_loops
from .solvers.impact_carry import clear_impacts
from .solvers.mass_splitting import update_support_loops
from .solvers.rows import respond_row
from .solvers.set_up import order_blocks, prepare_point
from .solvers.substep import iterate_in_order_loops
from .solvers.team_loop import goes_in_lanes, iterate_shared_loops
from .step_scalars import (BIASED_SWEEPS, MARGIN, MATCH_DISTANCE, OVERLAP_DEPTH, PAIR_REUSE_MARGIN, RELAX_SWEEPS,
                           RELAXATION, REUSE_D2, REUSE_SIN, SLEEP_ANGULAR, SLEEP_LINEAR, SLEEP_TIME, SLOP, STEP,
                           SUBSTEP, SUBSTEPS, WARM_FACTOR)


@repeat_launch
@ti.kernel
def begin_and_collide(b: ti.template(), speculative: ti.template(), kinds: ti.template(), awake: ti.template(),
                      dispatch: ti.template()):
    """Save the good state, clear the error flags, world inertias, broadphase, narrowphase
    (``awake``: of every body, or of a sleeping world's awake ones; awake.py; ``dispatch``: how
    the heavy loops run, dispatch.py). Margin, slop, overlap depth, step and reuse bounds: ``b.scalars``."""
    f = ti.static(b.scalars.f)
    margin, slop, h = f[MARGIN], f[SLOP], f[STEP]
    clear_error_flags(b.errors)
    save_good_state_loops(b.bodies, awake)
    update_world_inertia_loops(b.bodies, awake)
    build_dynamic_grid_loops(b.bp, b.shapes, b.bodies, margin, f[PAIR_REUSE_MARGIN], h, speculative, b.errors, awake,
                             dispatch)
    find_pairs_loops(b.bp, b.shapes, awake, dispatch)
    collide_pairs_loops(b.contacts, b.bp, b.shapes, b.bodies, b.pool, b.manifold_cache, margin, slop, f[OVERLAP_DEPTH],
                        h, speculative, f[REUSE_D2], f[REUSE_SIN], kinds, awake, dispatch)


@ti.func
def prepare_step_loops(b: ti.template(), blk: ti.template(), match_distance: ti.f32, warm_factor: ti.f32,
                       kind: ti.template(), mode: ti.template(), omega: ti.f32, split: ti.template(),
                       friction: ti.template(), dispatch: ti.template(), responds: ti.template() = True):
    """Rows and warm-start matching in one loop over the points, the schedule's adjacency
    (its split counts read both), then the row responses and springs (which read the
    split scales): each stage reads only its own point's earlier results, so these are
    the bits of the separate launches, in one dispatch. ``responds`` False: the team's lane
    copy works out the response shares and the responses (team_loop.iterate_shared_loops)."""
    clear_impacts(b.rows)
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for q in range(b.contacts.count[None]):
        prepare_point(b, q, match_distance, warm_factor, responds)
    order_blocks(b, blk, kind, mode, omega)
    if ti.static(responds):
        ti.loop_config(serialize=ti.static(dispatch.serial))
        for q in range(b.contacts.count[None]):
            respond_row(b.rows, b.contacts, b.bodies, blk, split, friction, q)


@repeat_launch
@ti.kernel
def prepare_step(b: ti.template(), kind: ti.template(), mode: ti.template(), split: ti.template(),
                 friction: ti.template(), dispatch: ti.template()):
    """``prepare_step_loops`` with the block scratch ``b.blocks`` and the scalars of ``b.scalars``."""
    f = ti.static(b.scalars.f)
    prepare_step_loops(b, b.blocks, f[MATCH_DISTANCE], f[WARM_FACTOR], kind, mode, f[RELAXATION], split, friction,
                       dispatch)


@ti.func
def finish_step_loops(b: ti.template(), kind: ti.template(), substeps: ti.i32, awake: ti.template(), h: ti.f32,
                      lin: ti.f32, ang: ti.f32, rest_time: ti.f32, dispatch: ti.template()):
    """The bodies' finite check (velocity and pose), their support loads and the contact store
    for the next step; in a sleeping world also the rest timers and islands
    (sleep.rest_and_label_loops, its scalars after ``awake``)."""
    check_bodies_loops(b.bodies, b.errors, awake)
    update_support_loops(b.blocks, b.contacts, b.rows, b.bodies, awake, kind, dispatch)
    store_contacts_loops(b.history, b.contacts, b.rows, b.shapes, substeps, awake, dispatch)
    if ti.static(awake.compact):
        rest_and_label_loops(awake, b.contacts, b.bodies, h, lin, ang, rest_time, True)


@repeat_launch
@ti.kernel
def finish_step(b: ti.template(), kind: ti.template(), awake: ti.template(), dispatch: ti.template()):
    """``finish_step_loops`` with the scalars of ``b.scalars``."""
    f = ti.static(b.scalars.f)
    finish_step_loops(b, kind, b.scalars.i[SUBSTEPS], awake, f[STEP], f[SLEEP_LINEAR], f[SLEEP_ANGULAR],
                      f[SLEEP_TIME], dispatch)


@dataclass(frozen=True)
class SolveSwitches:
    """The compile-time switches of ``solve_step_in_order`` as one template argument: Taichi
    keys every launch on each template argument in Python (a few us apiece), and these change
    only with the solver and the effects. ``kind``, ``mode``, ``split``: the schedule's block,
    merge and scaled responses; ``friction``: rows.contact_switch; ``visit``: the sweep's
    order; ``warm``, ``track``: warm start, summed impulses; ``motion``: integrate.motion_switch."""

    kind: int
    mode: int
    split: bool
    friction: int
    visit: int
    warm: bool
    track: bool
    motion: int


_switches: dict = {}


def solve_switches(*values) -> SolveSwitches:
    """The one SolveSwitches of these values (a dictionary look-up, not a new object a step)."""
    found = _switches.get(values)
    if found is None:
        found = _switches[values] = SolveSwitches(*values)
    return found


@repeat_launch
@ti.kernel
def solve_step_in_order(b: ti.template(), sw: ti.template(), awake: ti.template(), dispatch: ti.template()):
    """``prepare_step``, the iteration loop on one thread (substep.iterate_in_order) and
    ``finish_step`` in one launch, for a small world whose step has nothing to do on the host
    in between (no colouring, restitution pass or impact watch): the same loops in the same
    order, so the same bits, one launch instead of three (each ~0.1-0.3 ms of Python here). Its
    scalars are in ``b.scalars``, its block scratch is ``b.blocks`` (Schedule.adjacency_args),
    its switches in ``sw`` (SolveSwitches): each argument costs the launch Python."""
    f, n = ti.static(b.scalars.f, b.scalars.i)
    prepare_step_loops(b, b.blocks, f[MATCH_DISTANCE], f[WARM_FACTOR], sw.kind, sw.mode, f[RELAXATION], sw.split,
                       sw.friction, dispatch)
    iterate_in_order_loops(b, sw.kind, sw.visit, sw.friction, sw.warm, sw.track, awake, sw.motion, f[SUBSTEP],
                           n[SUBSTEPS], n[BIASED_SWEEPS], n[RELAX_SWEEPS])
    finish_step_loops(b, sw.kind, n[SUBSTEPS], awake, f[STEP], f[SLEEP_LINEAR], f[SLEEP_ANGULAR], f[SLEEP_TIME],
                      dispatch)


@repeat_launch
@ti.kernel
def solve_step_shared(b: ti.template(), sw: ti.template(), team: ti.template(), members: ti.i32,
                      awake: ti.template(), dispatch: ti.template()):
    """``solve_step_in_order`` for a world whose iteration loop the CPU threads share
    (team_loop.iterate_shared): ``prepare_step``'s parallel loops, the team's loop and
    ``finish_step``'s parallel loops, one after another as the three launches ran them, so the
    same bits, one launch (each ~0.1-0.3 ms of Python). ``team``, ``members``: Schedule.team.
    Where the team's sweeps go eight points at a time, the team also runs the set-up, as its
    first phases, and its lane copy works out the rows' response shares and responses on every
    thread (the same loops, in the same order, on the same inputs: the same bits)."""
    f, n = ti.static(b.scalars.f, b.scalars.i)
    in_team = ti.static(goes_in_lanes(sw.visit, sw.kind, sw.friction))
    if ti.static(not in_team):
        prepare_step_loops(b, b.blocks, f[MATCH_DISTANCE], f[WARM_FACTOR], sw.kind, sw.mode, f[RELAXATION], sw.split,
                           sw.friction, dispatch)
    iterate_shared_loops(team, b, sw.kind, sw.visit, sw.friction, sw.warm, sw.track, awake, sw.motion, f[SUBSTEP],
                         n[SUBSTEPS], n[BIASED_SWEEPS], n[RELAX_SWEEPS], members, in_team, sw.split, sw.mode, in_team)
    finish_step_loops(b, sw.kind, n[SUBSTEPS], awake, f[STEP], f[SLEEP_LINEAR], f[SLEEP_ANGULAR], f[SLEEP_TIME],
                      dispatch)


@ti.kernel
def after_upload(b: ti.template(), margin: ti.f32, bodies: ti.i32, shapes: ti.i32, planes: ti.i32, dynamic: ti.i32,
                 cell_size: ti.f32, static_cell_size: ti.f32, static_lo: ti.math.vec3, static_hi: ti.math.vec3):
    """After build.upload's rows: the counts and the grids' scalars, the bodies' world inertias, first
    good state and shape bounds, and no contact, history, remembered manifold or error flag from
    the buffer's previous world, in one launch (as Bodies.finish_upload, ShapeTable.finish_upload
    and six kernels, the first world of a process loaded five more kernel instances and a dozen
    field accessors, ~15 ms each)."""
    b.bodies.count[None] = bodies
    b.shapes.count[None] = shapes
    b.shapes.plane_count[None] = planes
    b.shapes.dynamic_count[None] = dynamic
    b.bp.cell_size[None] = cell_size
    b.bp.static_cell_size[None] = static_cell_size
    b.bp.static_lo[None] = static_lo
    b.bp.static_hi[None] = static_hi
    clear_error_flags(b.errors)
    update_world_inertia_loops(b.bodies, EVERY)
    save_good_state_loops(b.bodies, EVERY)
    compute_all_aabbs_loops(b.bp, b.shapes, b.bodies, margin)
    clear_contacts_loops(b.contacts, b.bp)
    clear_history_loops(b.history)
    clear_cache_loops(b.manifold_cache)
