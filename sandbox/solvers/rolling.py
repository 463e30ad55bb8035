"""Rolling and torsional friction rows (Bullet's rolling and spinning friction): three angular
rows per contact point on the bodies' relative angular velocity, each bounded by a lever arm
times the point's normal impulse. Compiled in only with the ROLLING bit of a sweep's friction
switch (rows.contact_switch); solved after the point's normal row (rows.solve_point).
"""

import taichi as ti

from ..math3d import dot, mat_vec

vec3 = ti.math.vec3


@ti.func
def respond_rolling(rows: ti.template(), c: ti.template(), q: ti.i32, ia, ib):
    """Once per step: the angular rows' velocity responses (``ia``, ``ib``: each body's scaled
    I^-1) and the inverses of their effective masses (n, t1, t2)."""
    rows.roll_resp_a[q] = ia
    rows.roll_resp_b[q] = ib
    both = ia + ib
    k_roll = vec3(dot(c.normal[q], mat_vec(both, c.normal[q])), dot(rows.t1[q], mat_vec(both, rows.t1[q])),
                  dot(rows.t2[q], mat_vec(both, rows.t2[q])))
    inv_k_roll = vec3(0.0)  # 0: neither body can turn (both static or infinitely inert)
    for e in ti.static(range(3)):
        if k_roll[e] > 0.0:
            inv_k_roll[e] = 1.0 / k_roll[e]
    rows.inv_k_roll[q] = inv_k_roll


@ti.func
def rolling_impulse(rows: ti.template(), c: ti.template(), q: ti.i32) -> vec3:
    """Point q's accumulated torsional and rolling impulses as one angular impulse on body b."""
    lr = rows.lam_roll[q]
    return c.normal[q] * lr[0] + rows.t1[q] * lr[1] + rows.t2[q] * lr[2]


@ti.func
def solve_rolling(rows: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32, wa: vec3, wb: vec3,
                  lam_n: ti.f32):
    """Torsional friction (about the normal) then rolling friction (about the tangents) of point
    q: angular rows on the relative angular velocity, each bounded by its lever arm times the
    point's normal impulse (the larger of the two bodies' coefficients, Bullet's spinning and
    rolling friction), the rolling pair projected onto a disk like sliding friction. Their
    impulses are warm started within the step (mass_splitting._warm_delta) like the others."""
    arm = ti.max(bodies.rolling[c.body_a[q]], bodies.rolling[c.body_b[q]]) * lam_n  # [N m s] (rolling, torsional)
    ia = rows.roll_resp_a[q]
    ib = rows.roll_resp_b[q]
    inv_k = rows.inv_k_roll[q]
    lr = rows.lam_roll[q]
    n = c.normal[q]
    t1 = rows.t1[q]
    t2 = rows.t2[q]
    if inv_k[0] > 0.0:
        tn = ti.min(ti.max(lr[0] - dot(wb - wa, n) * inv_k[0], -arm[1]), arm[1])
        d = (tn - lr[0]) * n
        wa -= mat_vec(ia, d)
        wb += mat_vec(ib, d)
        lr[0] = tn
        dw = wb - wa
        r1 = lr[1] - dot(dw, t1) * inv_k[1]
        r2 = lr[2] - dot(dw, t2) * inv_k[2]
        mag = ti.sqrt(r1 * r1 + r2 * r2)
        if mag > arm[0]:
            r1 *= arm[0] / mag
            r2 *= arm[0] / mag
        d = (r1 - lr[1]) * t1 + (r2 - lr[2]) * t2
        wa -= mat_vec(ia, d)
        wb += mat_vec(ib, d)
        lr[1] = r1
        lr[2] = r2
        rows.lam_roll[q] = lr
    return wa, wb
