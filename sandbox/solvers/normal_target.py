"""What a contact's normal row asks for in a sweep (solvers/rows.py solves it): the point's
separation now, a gap's speculative target, a penetration's push-out by its spring (capped in
speed, and read with the face's rocking share where the stability limit capped the spring,
contact_spring.rocking_share), and whether that push is fast enough to earn the substep a second
relax sweep. Kept apart from the row update because it is the one place a row's *position* enters
the velocity solve."""

import taichi as ti

from ..math3d import dot, quat_rotate
from .contact_spring import INV_H, MAX_PUSH, OVERLAP_PUSH, RELAX_PUSH

BIASED, RELAX, RESTITUTION = 0, 1, 2
"""Sweep modes: the biased sweep (soft rows, the spring's push-out), the relax sweep (rigid, no
push) and the restitution pass."""


@ti.func
def current_separation(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32) -> ti.f32:
    """Separation of point q now, from its value at the step start and the bodies' motion since."""
    a = c.body_a[q]
    b = c.body_b[q]
    ra = rows.ra[q]
    rb = rows.rb[q]
    da = bodies.moved[a] + quat_rotate(bodies.rot[a], rows.ra_body[q]) - ra
    db = bodies.moved[b] + quat_rotate(bodies.rot[b], rows.rb_body[q]) - rb
    return c.sep[q] + dot(c.normal[q], db - da)


@ti.func
def touching_depth(rows: ti.template(), c: ti.template(), q: ti.i32) -> ti.f32:
    """[m] The mean separation of the touching points (separation <= 0 as the biased sweep reads
    it) of point q's manifold; a point hovering above the face does not count."""
    m = c.manifold[q]
    total = 0.0
    count = 0
    for k in range(c.m_start[m], c.m_start[m] + c.m_count[m]):
        if rows.sep_now[k] <= 0.0:
            total += rows.sep_now[k]
            count += 1
    return total / ti.cast(ti.max(count, 1), ti.f32)


@ti.func
def bias_push(rows: ti.template(), c: ti.template(), q: ti.i32, s: ti.f32) -> ti.f32:
    """[m/s] The biased sweep's target of penetrating point q (separation ``s`` < 0): the
    spring's push-out, negative, at most ``max_push_speed``, and at most ``overlap_push_speed``
    while the pair is one found overlapping (manifold_cache.py). A row the stability limit capped
    reads its depth beyond its manifold's mean up to ``rocking`` times over: a face resists
    rocking more stiffly than the capped spring (contact_spring.rocking_share)."""
    cap = rows.params[MAX_PUSH]
    if c.overlap[q]:
        cap = ti.min(cap, rows.params[OVERLAP_PUSH])
    depth = s
    if rows.rocking[q] > 0.0:
        depth = s + rows.rocking[q] * (s - touching_depth(rows, c, q))
    return ti.max(rows.rate[q] * ti.min(depth + c.slop[q], 0.0), -cap)


@ti.func
def pushes_fast(rows: ti.template(), c: ti.template(), q: ti.i32) -> ti.i32:
    """1 when point q's biased row pushes out faster than ``Settings.relax_push_speed`` (> 0; its
    separation as the biased sweep reads it): the Jacobi family then relaxes the substep twice
    (solvers/substep.py)."""
    s = rows.sep_now[q]
    fast = 0
    if s < 0.0:
        if -bias_push(rows, c, q, s) > rows.params[RELAX_PUSH]:
            fast = 1
    return fast


@ti.func
def normal_target(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32, mode: ti.template(),
                  keep: ti.template() = True):
    """(target velocity b, compliance gamma) of point q's normal row: the row asks for
    n . v_rel + b + gamma lambda >= 0. Gaps are speculative targets s / h; a penetration
    gets the spring's bias in BIASED mode; BIASED rows are soft (gamma) either way, RELAX
    rows rigid.

    The separation changes only when positions do, i.e. between a substep's biased and
    relax sweeps: the relax sweep (the first to run after a position update) computes it
    and keeps it in ``sep_now`` for the next substep's biased sweep (prepare_rows seeds it
    for the first), so the two quaternion rotations are paid once per substep. ``keep`` False
    (a residual read, compute_residuals) computes it without keeping it: reading the solver's
    state never changes what its next sweep sees."""
    target = 0.0
    gamma = 0.0
    s = 0.0
    if ti.static(mode == BIASED):
        s = rows.sep_now[q]
    else:
        s = current_separation(rows, c, bodies, q)
        if ti.static(keep):
            rows.sep_now[q] = s
    if s > 0.0:
        target = s * rows.params[INV_H]
    elif ti.static(mode == BIASED):
        target = bias_push(rows, c, q, s)
    if ti.static(mode == BIASED):
        gamma = rows.gamma[q]
    return target, gamma
