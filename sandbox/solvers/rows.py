"""Contact rows shared by every solver: anchors, tangent basis, unit responses,
accumulated impulses, and the row update itself. Written once so that PGS, Jacobi
and mass splitting differ only in how they visit rows and combine impulses
(house rule 6).

Per point we keep each body's share of the unit response separately,
``k_a = 1/m_a + (r_a x e)^T I_a^-1 (r_a x e)`` (and ``k_b``) for e = n, t1, t2,
so a schedule can form ``K~ = s_a k_a + s_b k_b`` with its own mass scale
(s = 1 for PGS, s = n_body for mass splitting; method.md 1.4).

Time stepping is Box2D v3's soft step (Catto, "Solver2D", 2024): one *iteration*
is one substep of h / iterations: gravity, warm start, one biased sweep,
position update, one relax sweep (more of each below 8 iterations,
Settings.step_sweeps). Between substeps the separation of every
point is updated from the bodies' motion since the step began (the Jacobians
stay those of the step start), so the solver sees penetration resolve as it
happens instead of extrapolating from a stale gap. Contacts are soft
(method.md 1.9): penetration beyond the slop is a spring-damper, one per row
(contact_spring.py says how stiff, and why no stiffer); the normal row solves the
regularised problem ``0 <= lambda  _|_  J u + b + gamma lambda >= 0``, bias ``b`` =
rate x penetration, compliance ``gamma = K / c`` from the *unsplit* response K. A
schedule with split response K~ updates ``dl = -(J u + b + gamma lambda) /
(K~ + gamma)``, which has the same fixed point as the unsplit row: softness is
physics, and mass splitting must not change it. A loaded row is preloaded (contact_spring.py):
its impulse up to the preload P meets no compliance, ``J u + b + gamma max(lambda - P, 0) >= 0``,
so a tall pile need not sag by its capped spring's measure. Gaps (s > 0) are speculative
targets s / h; in the biased sweep they keep the spring's compliance, as Rapier's soft
rows do, so that a row's update is continuous where its gap closes (the earlier rows
stepped gaps with the soft denominator but without the compliance term, an update of
neither kind; made rigid, as Box2D v3 does, the top card of the leaning-planks house
slid off at 4 iterations: measured, docs/method-notes.md). The relax sweep is rigid
with no spring term: the positions were corrected by the biased velocity, but the
push-out velocity does not survive as momentum, so position correction cannot pump
energy into a stack.

Restitution is a normal-only pass after the substeps (Box2D v3's restitution stage),
against the approach speed measured before the step, for every point that carried an
impulse during the step (also one first caught as a speculative gap: its last substep
may carry none), repeated until the split schedules converge too (solvers/schedule.py);
its impulse is kept apart (``lam_bounce``) so the next step does not warm start with it.

A substep's impulses warm start the next; an impact row's carry is clamped first
(impact_carry.py).

Impulses are per substep; the contact history stores them per step
(x iterations) so changing the iteration count keeps warm starting consistent.
When asked (restitution, breakable bodies, ``World.track_impulses``) each substep's
impulses are summed into ``lam_step``, the step's impulse (step_impulses.py).
"""

import taichi as ti

from ..lanes import lane_capacity
from ..math3d import cross, dot, mat_mul, mat_vec, plane_basis, quat_rotate_inv
from .contact_spring import PARAM_COUNT, RESTITUTION_THRESHOLD, row_spring, supported_load
from .impact_carry import clear_impacts, list_carry_rows, note_impact
from .normal_target import BIASED, RELAX, RESTITUTION, normal_target  # noqa: F401  (the sweep modes live there)
from .rolling import respond_rolling, solve_rolling
from .light_bodies import light_pair
from .split_scales import block_scales

vec3 = ti.math.vec3


@ti.data_oriented
class Rows:
    def __init__(self, capacity: int):
        c = lane_capacity(max(16, capacity))
        self.capacity = c
        self.ra = ti.Vector.field(3, ti.f32, c)
        self.rb = ti.Vector.field(3, ti.f32, c)
        self.t1 = ti.Vector.field(3, ti.f32, c)
        self.t2 = ti.Vector.field(3, ti.f32, c)
        self.k_a = ti.Vector.field(3, ti.f32, c)  # body a's unit response share for (n, t1, t2)
        self.k_b = ti.Vector.field(3, ti.f32, c)
        self.ra_body = ti.Vector.field(3, ti.f32, c)  # anchors in the bodies' frames at the step start
        self.rb_body = ti.Vector.field(3, ti.f32, c)
        self.approach = ti.field(ti.f32, c)  # [m/s] normal velocity before the step (restitution)
        self.sep_now = ti.field(ti.f32, c)  # [m] separation at the last position update (normal_target)
        self.params = ti.field(ti.f32, PARAM_COUNT)  # this step's constants (contact_spring.row_params)
        self.lam = ti.Vector.field(3, ti.f32, c)  # accumulated impulses (n, t1, t2) [N s]
        self.counted = ti.field(ti.i32, c)  # the point's block counts in its bodies' n_b (mass_splitting.py)
        # per step, with the schedule's mass scale s (prepare_response): rows e = n, t1, t2
        self.ang_a = ti.Matrix.field(3, 3, ti.f32, c)  # r_a x e
        self.ang_b = ti.Matrix.field(3, 3, ti.f32, c)
        self.resp_a = ti.Matrix.field(3, 3, ti.f32, c)  # s_a I_a^-1 (r_a x e)
        self.resp_b = ti.Matrix.field(3, 3, ti.f32, c)
        self.lin_a = ti.field(ti.f32, c)  # s_a / m_a
        self.lin_b = ti.field(ti.f32, c)
        self.inv_k = ti.Vector.field(3, ti.f32, c)  # 1 / K~ of the rigid rows (n, t1, t2)
        self.inv_k_soft = ti.field(ti.f32, c)  # 1 / (K~_n + gamma) of the soft normal row
        self.rate = ti.field(ti.f32, c)  # [1/s] the normal row's bias rate (contact_spring.py)
        self.gamma = ti.field(ti.f32, c)  # the normal row's compliance gamma = K / c
        self.preload = ti.field(ti.f32, c)  # [N s] impulse per substep the normal row carries rigidly (contact_spring.py)
        self.rocking = ti.field(ti.f32, c)  # [1] extra weight of its depth beyond its face's mean (rocking_share)
        self.lam_roll = ti.Vector.field(3, ti.f32, c)  # [N m s] torsional (about n) and rolling (t1, t2) impulses
        # with rolling friction only (respond_row): s I^-1 of each body, 1 / K~ of the angular rows (n, t1, t2)
        self.roll_resp_a = ti.Matrix.field(3, 3, ti.f32, c)
        self.roll_resp_b = ti.Matrix.field(3, 3, ti.f32, c)
        self.inv_k_roll = ti.Vector.field(3, ti.f32, c)
        self.lam_step = ti.Vector.field(3, ti.f32, c)  # [N s] impulses summed over the step (when tracked)
        self.lam_bounce = ti.field(ti.f32, c)  # [N s] the restitution pass's normal impulse
        self.bounce_residual = ti.field(ti.f32, ())  # [m/s] largest bounce-row residual of the last sweep
        self.fast_push = ti.field(ti.i32, ())  # 1: a biased sweep of this substep pushed a row fast (pushes_fast)
        self.impacts = ti.field(ti.i32, ())  # 1: a row of this step is an impact (impact_carry.note_impact)
        self.carry_rows = ti.field(ti.i32, c)  # the points whose folded carry is clamped (impact_carry.list_carry_rows)
        self.carry_count = ti.field(ti.i32, ())
        self.residual = ti.field(ti.f32, c)  # squared LCP residual of the point's rows [(m/s)^2]


SLIDING, ROLLING = 1, 2
"""Bits of a sweep's ``friction`` switch (effects.py compiles each in only when some contact can
use it): the sliding-friction rows, and the torsional and rolling rows (``rolling.solve_rolling``)."""


def contact_switch(effects) -> int:
    """The sweeps' ``friction`` bits for an effects.CompiledEffects."""
    return (SLIDING if effects.friction else 0) | (ROLLING if effects.rolling_friction else 0)


@ti.func
def _share(inv_mass: ti.f32, inv_inertia: ti.template(), r: vec3, e: vec3) -> ti.f32:
    rxe = cross(r, e)
    return inv_mass + dot(rxe, mat_vec(inv_inertia, rxe))


@ti.func
def share_row(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32):
    """Point q's unit response shares k_a, k_b for (n, t1, t2), from its anchors and tangents
    (prepare_row's; respond_row and the impact clamp read them, nothing before them in a step)."""
    a = c.body_a[q]
    b = c.body_b[q]
    n = c.normal[q]
    ra = rows.ra[q]
    rb = rows.rb[q]
    t1 = rows.t1[q]
    t2 = rows.t2[q]
    ima = bodies.inv_mass[a]
    imb = bodies.inv_mass[b]
    ia = bodies.inv_inertia_world[a]
    ib = bodies.inv_inertia_world[b]
    rows.k_a[q] = vec3(_share(ima, ia, ra, n), _share(ima, ia, ra, t1), _share(ima, ia, ra, t2))
    rows.k_b[q] = vec3(_share(imb, ib, rb, n), _share(imb, ib, rb, t1), _share(imb, ib, rb, t2))


@ti.func
def prepare_row(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32,
                shares: ti.template() = True):
    """Point q's anchors, tangent basis, unit response shares (``shares`` False: left to the
    team's lane copy, team_loop.iterate_shared_loops) and approach speed."""
    a = c.body_a[q]
    b = c.body_b[q]
    p = c.point[q]
    n = c.normal[q]
    ra = p - bodies.pos[a]
    rb = p - bodies.pos[b]
    t1, t2 = plane_basis(n)
    rows.ra[q] = ra
    rows.rb[q] = rb
    rows.ra_body[q] = quat_rotate_inv(bodies.rot[a], ra)
    rows.rb_body[q] = quat_rotate_inv(bodies.rot[b], rb)
    rows.t1[q] = t1
    rows.t2[q] = t2
    if ti.static(shares):
        share_row(rows, c, bodies, q)
    v_rel = bodies.lin_vel[b] + cross(bodies.ang_vel[b], rb) - bodies.lin_vel[a] - cross(bodies.ang_vel[a], ra)
    rows.approach[q] = dot(v_rel, n)
    note_impact(rows, c, q)
    rows.sep_now[q] = c.sep[q]  # the bodies have not moved since the narrowphase
    rows.lam_step[q] = vec3(0.0)
    rows.lam_roll[q] = vec3(0.0)  # not carried from step to step: each step's first substep starts at 0
    rows.lam_bounce[q] = 0.0


@ti.func
def prepare_rows_loops(rows: ti.template(), c: ti.template(), bodies: ti.template()):
    clear_impacts(rows)
    for q in range(c.count[None]):
        prepare_row(rows, c, bodies, q)
    list_carry_rows(rows, c)


@ti.kernel
def prepare_rows(rows: ti.template(), c: ti.template(), bodies: ti.template()):
    prepare_rows_loops(rows, c, bodies)


@ti.func
def respond_row(rows: ti.template(), c: ti.template(), bodies: ti.template(), scale: ti.template(),
                split: ti.template(), friction: ti.template(), q: ti.i32):
    """What a sweep needs of point q, once per step: the angular Jacobians r x e of both
    bodies for e = n, t1, t2, the velocity responses s I^-1 (r x e) and s / m, the normal
    row's spring (contact_spring.py: it needs the split response), and the inverse
    effective masses of the three rows (the normal one soft and rigid).

    ``s`` is the schedule's scale of the body's inverse mass and inertia (split_scales.block_scales
    when ``split``, else 1: PGS), used in the effective mass *and* when propagating the
    impulse into the block's velocity copies, which keeps a mass-split block consistent
    (method.md 1.5). The compliance gamma comes from the *unsplit* response (module
    docstring). Inverse inertias are those of the step start, as before: the rows of a
    step are linear in the impulses, so the sweep is dot products and axpys only; the
    effective masses are stored inverted, so a row multiplies instead of dividing (two
    roundings instead of one; measured ~9 % of the pile's iteration loop, where a division's
    latency sits on each row's dependency chain)."""
    a = c.body_a[q]
    b = c.body_b[q]
    sa = 1.0
    sb = 1.0
    if ti.static(split):
        sa, sb = block_scales(scale, rows, q, a, b)
    ia = bodies.inv_inertia_world[a] * sa
    ib = bodies.inv_inertia_world[b] * sb
    ra = rows.ra[q]
    rb = rows.rb[q]
    ja = ti.Matrix.rows([cross(ra, c.normal[q]), cross(ra, rows.t1[q]), cross(ra, rows.t2[q])])
    jb = ti.Matrix.rows([cross(rb, c.normal[q]), cross(rb, rows.t1[q]), cross(rb, rows.t2[q])])
    rows.ang_a[q] = ja
    rows.ang_b[q] = jb
    rows.resp_a[q] = mat_mul(ia, ja.transpose()).transpose()  # row e = s_a I_a^-1 (r_a x e)
    rows.resp_b[q] = mat_mul(ib, jb.transpose()).transpose()
    rows.lin_a[q] = bodies.inv_mass[a] * sa
    rows.lin_b[q] = bodies.inv_mass[b] * sb
    k = sa * rows.k_a[q] + sb * rows.k_b[q]
    k_true = rows.k_a[q][0] + rows.k_b[q][0]
    load, slow_load = supported_load(rows.params, c, bodies, q)
    light = light_pair(scale, a, b)  # a light body's row: its extra sweeps' limit and damping (light_bodies.py)
    rate, gamma, preload, rocking = row_spring(rows.params, k_true, k[0], load, slow_load, c.size[q], light)
    rows.rate[q] = rate
    rows.gamma[q] = gamma
    rows.preload[q] = preload
    rows.rocking[q] = rocking
    rows.inv_k[q] = 1.0 / k
    rows.inv_k_soft[q] = 1.0 / (k[0] + gamma)
    if ti.static(friction & ROLLING):  # the angular rows' responses (rolling.solve_rolling)
        respond_rolling(rows, c, q, ia, ib)


@ti.func
def prepare_response_loops(rows: ti.template(), c: ti.template(), bodies: ti.template(), scale: ti.template(),
                           split: ti.template(), friction: ti.template()):
    for q in range(c.count[None]):
        respond_row(rows, c, bodies, scale, split, friction, q)


@ti.kernel
def prepare_response(rows: ti.template(), c: ti.template(), bodies: ti.template(), scale: ti.template(),
                     split: ti.template(), friction: ti.template()):
    prepare_response_loops(rows, c, bodies, scale, split, friction)


@ti.func
def _row(m, r: ti.template()) -> vec3:
    return vec3(m[r, 0], m[r, 1], m[r, 2])


@ti.func
def solve_point(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32,
                va: vec3, wa: vec3, vb: vec3, wb: vec3, mode: ti.template(), friction: ti.template()):
    """Friction rows then the normal row of point q, on velocity copies, with the
    responses of ``prepare_response`` (which carry the schedule's mass scale).

    Friction is an isotropic cone: the tangent impulse is projected onto the disk of
    radius mu * lambda_n. The normal row goes last so non-penetration has the final
    word (Box2D v3). ``mode``: BIASED (soft, with position bias), RELAX (rigid, no
    bias) or RESTITUTION (normal row only, towards -e times the approach speed).
    ``friction`` (bits SLIDING, ROLLING) compiles in the sliding-friction rows and the
    torsional and rolling rows (``rolling.solve_rolling``); 0 (a scene without the friction effect)
    compiles every friction row away. The angular rows come after the normal row, as in
    Box2D v3, so that their bound is this sweep's normal impulse: bounded by the one before
    it, the last (relax) sweep of a substep capped them at the biased sweep's share of the
    substep's load, and a spinning sphere slowed 13 % too little while it settled. Only a
    rolling row on an off-centre point moves the normal velocity, by less than mu_r lambda_n
    allows, and the next sweep sees it.
    """
    ma = rows.lin_a[q]
    mb = rows.lin_b[q]
    ja = rows.ang_a[q]
    jb = rows.ang_b[q]
    n = c.normal[q]
    inv_k = rows.inv_k[q]
    lam = rows.lam[q]
    if ti.static(mode != RESTITUTION and (friction & SLIDING)):
        t1 = rows.t1[q]
        t2 = rows.t2[q]
        ra_ = rows.resp_a[q]
        rb_ = rows.resp_b[q]
        dl = vb - va
        f1 = lam[1] - (dot(dl, t1) + dot(wb, _row(jb, 1)) - dot(wa, _row(ja, 1))) * inv_k[1]
        f2 = lam[2] - (dot(dl, t2) + dot(wb, _row(jb, 2)) - dot(wa, _row(ja, 2))) * inv_k[2]
        limit = c.friction[q] * lam[0]
        mag = ti.sqrt(f1 * f1 + f2 * f2)
        if mag > limit:
            s = limit / mag
            f1 *= s
            f2 *= s
        d1 = f1 - lam[1]
        d2 = f2 - lam[2]
        imp = t1 * d1 + t2 * d2
        va -= ma * imp
        wa -= _row(ra_, 1) * d1 + _row(ra_, 2) * d2
        vb += mb * imp
        wb += _row(rb_, 1) * d1 + _row(rb_, 2) * d2
        lam[1] = f1
        lam[2] = f2
    # normal row
    if ti.static(mode == RESTITUTION):
        # the bounce, on its own accumulator: towards -e x the approach speed before the step
        e = c.restitution[q]
        vn0 = rows.approach[q]
        if e > 0.0 and vn0 < -rows.params[RESTITUTION_THRESHOLD] and rows.lam_step[q][0] > 0.0:
            vn = dot(vb - va, n) + dot(wb, _row(jb, 0)) - dot(wa, _row(ja, 0))
            lb = rows.lam_bounce[q]
            nb = ti.max(lb - (vn + e * vn0) * inv_k[0], 0.0)
            if nb > 0.0 or vn + e * vn0 < 0.0:  # not converged while the row still wants to change
                ti.atomic_max(rows.bounce_residual[None], ti.abs(vn + e * vn0))
            d = nb - lb
            va -= ma * d * n
            wa -= _row(rows.resp_a[q], 0) * d
            vb += mb * d * n
            wb += _row(rows.resp_b[q], 0) * d
            rows.lam_bounce[q] = nb
    else:
        target, gamma = normal_target(rows, c, bodies, q, mode)
        vn = dot(vb - va, n) + dot(wb, _row(jb, 0)) - dot(wa, _row(ja, 0))
        ln = lam[0] - (vn + target) * inv_k[0]
        if ti.static(mode == BIASED):
            pre = rows.preload[q]
            if ln > pre:  # compliance acts on the impulse beyond the preload only
                ln = lam[0] - (vn + target + gamma * (lam[0] - pre)) * rows.inv_k_soft[q]
        ln = ti.max(ln, 0.0)
        d = ln - lam[0]
        va -= ma * d * n
        wa -= _row(rows.resp_a[q], 0) * d
        vb += mb * d * n
        wb += _row(rows.resp_b[q], 0) * d
        lam[0] = ln
        rows.lam[q] = lam
        if ti.static(friction & ROLLING):
            wa, wb = solve_rolling(rows, c, bodies, q, wa, wb, ln)
    return va, wa, vb, wb


@ti.func
def point_impulse(rows: ti.template(), c: ti.template(), q: ti.i32) -> vec3:
    lam = rows.lam[q]
    return c.normal[q] * lam[0] + rows.t1[q] * lam[1] + rows.t2[q] * lam[2]


@ti.kernel
def compute_residuals(rows: ti.template(), c: ti.template(), bodies: ti.template(), mode: ti.template()):
    """Per point squared natural-map residual of the velocity-level LCP (method.md M1/M2) of
    the BIASED (soft) or RELAX (rigid) problem: w = n . v_rel + b + gamma max(lambda - P, 0)
    (P the row's preload, contact_spring.py)."""
    for q in range(c.count[None]):
        a = c.body_a[q]
        b = c.body_b[q]
        ra = rows.ra[q]
        rb = rows.rb[q]
        dv = bodies.lin_vel[b] + cross(bodies.ang_vel[b], rb) - bodies.lin_vel[a] - cross(bodies.ang_vel[a], ra)
        k = rows.k_a[q] + rows.k_b[q]
        lam = rows.lam[q]
        target, gamma = normal_target(rows, c, bodies, q, mode, False)
        w = dot(dv, c.normal[q]) + target + gamma * ti.max(lam[0] - rows.preload[q], 0.0)
        rn = ti.min(w, (k[0] + gamma) * lam[0])
        # friction: distance of lambda_t from the projection of its gradient step onto the disk
        g1 = lam[1] - dot(dv, rows.t1[q]) / k[1]
        g2 = lam[2] - dot(dv, rows.t2[q]) / k[2]
        limit = c.friction[q] * lam[0]
        mag = ti.sqrt(g1 * g1 + g2 * g2)
        if mag > limit:
            s = limit / ti.max(mag, 1e-30)
            g1 *= s
            g2 *= s
        r1 = k[1] * (lam[1] - g1)
        r2 = k[2] * (lam[2] - g2)
        rows.residual[q] = rn * rn + r1 * r1 + r2 * r2
