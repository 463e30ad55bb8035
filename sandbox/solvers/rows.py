"""Contact rows shared by every solver: anchors, tangent basis, unit responses, bias,
accumulated impulses. Written once so that PGS, Jacobi and mass splitting differ
only in how they visit rows and combine impulses (house rule 6).

Per point we keep each body's share of the unit response separately,
``k_a = 1/m_a + (r_a x e)^T I_a^-1 (r_a x e)`` (and ``k_b``) for e = n, t1, t2,
so a schedule can form ``K~ = s_a k_a + s_b k_b`` with its own mass scale
(s = 1 for PGS and Jacobi, s = n_body for mass splitting; method.md 1.4).
The bias is physical and computed from the geometry only, never from K~
(method.md 1.9): Baumgarte beyond the slop with a capped push speed,
speculative ``sep / h`` for gaps, and restitution for fast approaches.
"""


import taichi as ti

from ..math3d import plane_basis

vec3 = ti.math.vec3


@ti.data_oriented
class Rows:
    def __init__(self, capacity: int):
        c = max(16, capacity)
        self.capacity = c
        self.ra = ti.Vector.field(3, ti.f32, c)
        self.rb = ti.Vector.field(3, ti.f32, c)
        self.t1 = ti.Vector.field(3, ti.f32, c)
        self.t2 = ti.Vector.field(3, ti.f32, c)
        self.k_a = ti.Vector.field(3, ti.f32, c)  # body a's unit response share for (n, t1, t2)
        self.k_b = ti.Vector.field(3, ti.f32, c)
        self.bias = ti.field(ti.f32, c)  # [m/s] target: n . v_rel + bias >= 0
        self.lam = ti.Vector.field(3, ti.f32, c)  # accumulated impulses (n, t1, t2) [N s]
        self.residual = ti.field(ti.f32, c)  # squared LCP residual of the point's rows [(m/s)^2]


@ti.func
def _share(inv_mass: ti.f32, inv_inertia: ti.template(), r: vec3, e: vec3) -> ti.f32:
    rxe = r.cross(e)
    return inv_mass + rxe.dot(inv_inertia @ rxe)


@ti.kernel
def prepare_rows(rows: ti.template(), c: ti.template(), bodies: ti.template(), h: ti.f32,
                 slop: ti.f32, baumgarte: ti.f32, max_push: ti.f32, restitution_threshold: ti.f32):
    for q in range(c.count[None]):
        a = c.body_a[q]
        b = c.body_b[q]
        p = c.point[q]
        n = c.normal[q]
        ra = p - bodies.pos[a]
        rb = p - bodies.pos[b]
        t1, t2 = plane_basis(n)
        ima = bodies.inv_mass[a]
        imb = bodies.inv_mass[b]
        ia = bodies.inv_inertia_world[a]
        ib = bodies.inv_inertia_world[b]
        rows.ra[q] = ra
        rows.rb[q] = rb
        rows.t1[q] = t1
        rows.t2[q] = t2
        rows.k_a[q] = vec3(_share(ima, ia, ra, n), _share(ima, ia, ra, t1), _share(ima, ia, ra, t2))
        rows.k_b[q] = vec3(_share(imb, ib, rb, n), _share(imb, ib, rb, t1), _share(imb, ib, rb, t2))
        sep = c.sep[q]
        bias = 0.0
        if sep > 0.0:
            bias = sep / h  # speculative: the gap may close exactly this step
        elif sep < -slop:
            bias = ti.max(baumgarte / h * (sep + slop), -max_push)
        v_rel = bodies.lin_vel[b] + bodies.ang_vel[b].cross(rb) - bodies.lin_vel[a] - bodies.ang_vel[a].cross(ra)
        vn = v_rel.dot(n)
        e = c.restitution[q]
        if e > 0.0 and vn < -restitution_threshold and sep + vn * h < 0.0:
            bias = ti.min(bias, e * vn)
        rows.bias[q] = bias


@ti.func
def solve_point(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32,
                va: vec3, wa: vec3, vb: vec3, wb: vec3, sa: ti.f32, sb: ti.f32):
    """Friction rows then the normal row of point q, on velocity copies.

    ``sa``/``sb`` scale body a's/b's inverse mass and inertia, both in the
    effective mass and when propagating the impulse into the copies, which keeps
    a mass-split block consistent (method.md 1.5). Friction is an isotropic cone:
    the tangent impulse is projected onto the disk of radius mu * lambda_n.
    The normal row goes last so non-penetration has the final word (Box2D v3).
    """
    a = c.body_a[q]
    b = c.body_b[q]
    ima = bodies.inv_mass[a] * sa
    imb = bodies.inv_mass[b] * sb
    ia = bodies.inv_inertia_world[a] * sa
    ib = bodies.inv_inertia_world[b] * sb
    ra = rows.ra[q]
    rb = rows.rb[q]
    n = c.normal[q]
    t1 = rows.t1[q]
    t2 = rows.t2[q]
    k = sa * rows.k_a[q] + sb * rows.k_b[q]
    lam = rows.lam[q]
    # friction
    dv = vb + wb.cross(rb) - va - wa.cross(ra)
    f1 = lam[1] - dv.dot(t1) / k[1]
    f2 = lam[2] - dv.dot(t2) / k[2]
    limit = c.friction[q] * lam[0]
    mag = ti.sqrt(f1 * f1 + f2 * f2)
    if mag > limit:
        s = limit / mag
        f1 *= s
        f2 *= s
    imp = t1 * (f1 - lam[1]) + t2 * (f2 - lam[2])
    va -= ima * imp
    wa -= ia @ ra.cross(imp)
    vb += imb * imp
    wb += ib @ rb.cross(imp)
    # normal
    dv = vb + wb.cross(rb) - va - wa.cross(ra)
    ln = ti.max(lam[0] - (dv.dot(n) + rows.bias[q]) / k[0], 0.0)
    imp = n * (ln - lam[0])
    va -= ima * imp
    wa -= ia @ ra.cross(imp)
    vb += imb * imp
    wb += ib @ rb.cross(imp)
    rows.lam[q] = vec3(ln, f1, f2)
    return va, wa, vb, wb


@ti.func
def point_impulse(rows: ti.template(), c: ti.template(), q: ti.i32) -> vec3:
    lam = rows.lam[q]
    return c.normal[q] * lam[0] + rows.t1[q] * lam[1] + rows.t2[q] * lam[2]


@ti.kernel
def compute_residuals(rows: ti.template(), c: ti.template(), bodies: ti.template()):
    """Per point squared natural-map residual of the velocity-level LCP (method.md M1/M2)."""
    for q in range(c.count[None]):
        a = c.body_a[q]
        b = c.body_b[q]
        ra = rows.ra[q]
        rb = rows.rb[q]
        dv = bodies.lin_vel[b] + bodies.ang_vel[b].cross(rb) - bodies.lin_vel[a] - bodies.ang_vel[a].cross(ra)
        k = rows.k_a[q] + rows.k_b[q]
        lam = rows.lam[q]
        w = dv.dot(c.normal[q]) + rows.bias[q]
        rn = ti.min(w, k[0] * lam[0])
        # friction: distance of lambda_t from the projection of its gradient step onto the disk
        g1 = lam[1] - dv.dot(rows.t1[q]) / k[1]
        g2 = lam[2] - dv.dot(rows.t2[q]) / k[2]
        limit = c.friction[q] * lam[0]
        mag = ti.sqrt(g1 * g1 + g2 * g2)
        if mag > limit:
            s = limit / ti.max(mag, 1e-30)
            g1 *= s
            g2 *= s
        r1 = k[1] * (lam[1] - g1)
        r2 = k[2] * (lam[2] - g2)
        rows.residual[q] = rn * rn + r1 * r1 + r2 * r2
