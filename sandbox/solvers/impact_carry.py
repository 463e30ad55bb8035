"""An impact row's warm start: between substeps it carries only the impulse that stops its
approach.

A substep's impulses warm start the next (Box2D v3's soft step, rows.py). The impulse that
stopped an impact in one substep is the whole impact: applied again it throws the bodies back at
their impact speed, and only a Gauss-Seidel sweep takes it back in time, so under the split
schedules an inelastic cube left the ground at 20 % of its impact speed (docs/method-notes.md,
"An inelastic impact bounced"). Resting and stacked rows are not impacts and keep the whole warm
start.

Where the warm start has its own pass (a step's first substep; every substep of the PGS
solvers) a row's carry is clamped before it is applied (``clamp_impact_carry``). The Jacobi
family's later substeps take their warm start from the previous substep's last relax sweep
(substep.folds_warm_start), on each block's own velocity copies, where no merged velocity is
known yet; there the carry is applied whole, and in a step with impact rows a short serial pass
after that sweep's gather takes back what each listed row (``list_carry_rows``) carried beyond
its stop (mass_splitting.clamp_folded_carries). A step without an impact row lists none, so its
bits are those of the plain fold. (Until 2026-12-02 such a step warm started every substep in a
pass of its own over all blocks instead: 2.2x the substep's cost on a landing pile,
docs/bench.md "Fourteenth pass".)
"""

import taichi as ti

from ..math3d import cross, dot, vec3
from .contact_spring import GRAVITY_REACH, INV_H, RESTITUTION_THRESHOLD, STEP_DT, params_gravity


@ti.func
def is_impact(rows: ti.template(), c: ti.template(), q: ti.i32) -> ti.i32:
    """Point q closed faster than ``restitution_threshold`` when the step began (prepare_row),
    and touches or closes its gap within the step at that speed plus what gravity adds (a box
    still falling towards a pile is not an impact yet)."""
    vn = rows.approach[q]
    closing = c.sep[q] + vn * rows.params[STEP_DT] - rows.params[GRAVITY_REACH]
    return ti.cast(vn < -rows.params[RESTITUTION_THRESHOLD] and closing <= 0.0, ti.i32)


@ti.func
def clear_impacts(rows: ti.template()):
    """Before the rows are prepared (a statement at a kernel's top level, ahead of its loop)."""
    rows.impacts[None] = 0


@ti.func
def note_impact(rows: ti.template(), c: ti.template(), q: ti.i32):
    """While point q is prepared (its approach just measured): an impact row flags the step, so
    that its carry rows are listed (``list_carry_rows``)."""
    if is_impact(rows, c, q):
        rows.impacts[None] = 1  # every impact row stores the same 1; clear_impacts cleared it


@ti.func
def clamps_carry(rows: ti.template(), c: ti.template(), q: ti.i32) -> ti.i32:
    """1: point q's carried impulse is capped at its stop (``clamp_impact_carry``): an impact,
    or a row already separating faster than the threshold when the step began (a bounce
    leaving, which needs no impulse)."""
    return ti.cast(is_impact(rows, c, q) or rows.approach[q] > rows.params[RESTITUTION_THRESHOLD], ti.i32)


@ti.func
def list_carry_rows(rows: ti.template(), c: ti.template()):
    """After the rows are prepared (a kernel's top level, after the loop that ran
    ``note_impact``): the rows a folded warm start clamps afterwards, in point order (a serial
    loop: the pass that reads them is a Gauss-Seidel one, so their order is part of the bits).
    None in a step without an impact row, whose folded substeps clamp nothing, as before."""
    rows.carry_count[None] = 0
    ti.loop_config(serialize=True)
    for q in range(c.count[None] * rows.impacts[None]):
        if clamps_carry(rows, c, q):
            rows.carry_rows[rows.carry_count[None]] = q
            rows.carry_count[None] += 1


@ti.func
def clamp_impact_carry(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32):
    """Before an impact row's impulses are applied again as a substep's warm start: keep at most
    the normal impulse that stops the approach the bodies have now (their velocities before the
    warm start, plus the substep's gravity), with full masses; its friction and rolling impulses
    shrink in proportion, so they stay in their cones.

    Why: the impulse that stopped an impact in one substep is the whole impact. Warm started
    again it throws the bodies back at their impact speed, and a split sweep takes only part of
    that back (a quarter-body corner steps short, ``split_relaxation``): an inelastic cube left
    at 20 % of its impact speed (docs/method-notes.md, "An inelastic impact bounced"). A
    row still closing keeps its impulse (an under-relaxed Jacobi row needs it to stop a fast
    projectile); rows that were not closing fast when the step began (resting, stacked) keep
    the whole warm start (is_impact says which rows are impacts). A row already separating faster
    than the threshold when the step began (a bounce leaving) needs no impulse: the same cap takes
    its carry to zero. Without it the step after a bounce threw the impact's impulse at the
    leaving bodies again, and a Jacobi world whose busiest body split its factor to 44 took back
    only ~4 / 44 of it a sweep: an e = 1 cube left 19 % too fast (docs/method-notes.md)."""
    lam = rows.lam[q]
    if lam[0] > 0.0 and clamps_carry(rows, c, q):
        a = c.body_a[q]
        b = c.body_b[q]
        g_h = params_gravity(rows) / rows.params[INV_H]
        va = bodies.lin_vel[a] + cross(bodies.ang_vel[a], rows.ra[q])
        vb = bodies.lin_vel[b] + cross(bodies.ang_vel[b], rows.rb[q])
        if bodies.inv_mass[a] > 0.0:
            va += g_h
        if bodies.inv_mass[b] > 0.0:
            vb += g_h
        stop = stopping_impulse(rows, c, q, va, vb)
        if stop < lam[0]:
            scale_carry(rows, q, stop / lam[0])


@ti.func
def stopping_impulse(rows: ti.template(), c: ti.template(), q: ti.i32, va: vec3, vb: vec3) -> ti.f32:
    """[N s] The normal impulse that stops point q's approach at the points' velocities va, vb
    (full masses), zero for a point already separating."""
    return ti.max(-dot(vb - va, c.normal[q]), 0.0) / (rows.k_a[q][0] + rows.k_b[q][0])


@ti.func
def scale_carry(rows: ti.template(), q: ti.i32, ratio: ti.f32):
    """Point q's carried impulses times ``ratio`` (< 1): normal, friction and rolling alike, so
    they stay in their cones."""
    rows.lam[q] = rows.lam[q] * ratio
    rows.lam_roll[q] *= ratio
