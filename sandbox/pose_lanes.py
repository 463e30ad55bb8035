"""The position update of a world with the gyroscopic term, eight bodies at a time, on the CPU's
vector units (the CPU team's pose phases, solvers/team_loop.py).

Why: the implicit gyroscopic solve (integrate._rotate_gyroscopic: the body-frame momentum, a
Newton step or none, the Cayley rotation) is ~250 floating-point operations a body and substep.
On the settled 1000-box pile it took 33 us of a 241 us substep on one core, on the falling pile
65 us (docs/bench.md, "Where the settled pile's substep goes"). Written point by point LLVM runs
it one body at a time; written on vectors of eight bodies' values, as the lane sweep does for
contact points (solvers/point_lanes.py), each operation is one 8-wide instruction: a pass over
the settled pile's bodies 45 -> 28 us on one core, the falling pile's 81 -> 32 us, and the pile's
step 3-4 % faster on two threads (docs/bench.md, "Eighteenth pass").

Every operation is ``integrate.advance_pose``'s, in its order, on the same floats (``fast_math``
is off, backend.py: LLVM packs operations, never reorders or contracts them), so the bits are the
same (tests/test_solvers.py compares the team's launch with the others; the state hashes). The
one branch, Newton's early stop, becomes a mask: a lane that has converged keeps its angular
velocity while the others take their next step, which is what the body alone would have kept.
The helpers below work on lists of eight-lane vectors (a 3-vector is three of them, a 3 x 3
matrix nine, row by row, a quaternion four).
"""

import taichi as ti

from .awake import body_id
from .integrate import DAMPING, NEWTON_STEPS, NEWTON_TOLERANCE
from .lanes import LANES

lanes = ti.types.vector(LANES, ti.f32)
COFACTOR = [(3 * ((i + 1) % 3) + (j + 1) % 3, 3 * ((i + 2) % 3) + (j + 2) % 3,
             3 * ((i + 2) % 3) + (j + 1) % 3, 3 * ((i + 1) % 3) + (j + 2) % 3) for j in range(3) for i in range(3)]
"""For entry 3 j + i of a 3 x 3 inverse, the row-major indices of E(i+1, j+1), E(i+2, j+2), E(i+2, j+1)
and E(i+1, j+2) (_inverse)."""
IDENTITY = [1.0 if k % 4 == 0 else 0.0 for k in range(9)]
POSE_ROWS = 19
"""Rows of a group of the position update's out-rows (point_lanes.LaneRows.poses): displacement
since the step began (3), position (3) and its remainder (3), orientation (4), angular velocity (3)
and, with damping, linear velocity (3). Storing the eight bodies' results as one group is what lets
LLVM pack the update into vector instructions (lanes.py)."""


@ti.func
def _norm_sqr3(a):
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2]


@ti.func
def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


@ti.func
def _mat_vec(m, v):
    """math3d.mat_vec: each sum starts from ``m[0, 0] v[0] 0``."""
    zero = m[0] * v[0] * 0
    return [((zero + m[3 * r] * v[0]) + m[3 * r + 1] * v[1]) + m[3 * r + 2] * v[2] for r in ti.static(range(3))]


@ti.func
def _mat_mul(a, b):
    """math3d.mat_mul."""
    zero = a[0] * b[0] * 0
    return [((zero + a[k - k % 3] * b[k % 3]) + a[k - k % 3 + 1] * b[3 + k % 3]) + a[k - k % 3 + 2] * b[6 + k % 3]
            for k in ti.static(range(9))]


@ti.func
def _skew(v, zero):
    """integrate._skew; ``zero``: eight lanes of 0.0 (the matrix's literal zeros)."""
    return [zero, -v[2], v[1], v[2], zero, -v[0], -v[1], v[0], zero]


@ti.func
def _inverse(m):
    """Taichi 1.7's ``Matrix.inverse`` of a 3 x 3 (matrix_ops.inverse): entry (j, i) is
    ``inv_det * (E(i + 1, j + 1) E(i + 2, j + 2) - E(i + 2, j + 1) E(i + 1, j + 2))``, E taking its
    indices modulo 3 (COFACTOR lists them)."""
    det = (m[0] * (m[4] * m[8] - m[7] * m[5])
           - m[3] * (m[1] * m[8] - m[7] * m[2])
           + m[6] * (m[1] * m[5] - m[4] * m[2]))
    inv_det = 1.0 / det
    return [inv_det * (m[COFACTOR[k][0]] * m[COFACTOR[k][1]] - m[COFACTOR[k][2]] * m[COFACTOR[k][3]])
            for k in ti.static(range(9))]


@ti.func
def _quat_mul(a, b):
    return [a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]]


@ti.func
def _quat_normalize(q):
    """math3d.quat_normalize: ``q / q.norm()``, the norm Taichi's (its sum, plus eps 0.0)."""
    n = ti.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] + 0.0)
    return [q[k] / n for k in ti.static(range(4))]


@ti.func
def lane_quat_rotate(q, v):
    """math3d.quat_rotate on eight lanes, its operations in its order (also the relax sweep's
    separations, solvers/point_lanes.py)."""
    x, y, z = q[1], q[2], q[3]
    t = [2.0 * (y * v[2] - z * v[1]), 2.0 * (z * v[0] - x * v[2]), 2.0 * (x * v[1] - y * v[0])]
    c = [y * t[2] - z * t[1], z * t[0] - x * t[2], x * t[1] - y * t[0]]
    return [v[k] + q[0] * t[k] + c[k] for k in ti.static(range(3))]


@ti.func
def _quat_rotate_inv(q, v):
    return lane_quat_rotate([q[0], -q[1], -q[2], -q[3]], v)


@ti.func
def advance_poses(out: ti.template(), bodies: ti.template(), awake: ti.template(), motion: ti.template(), h: ti.f32,
                  g: ti.i32, n: ti.i32):
    """``integrate.advance_pose`` with the GYROSCOPIC bit for the bodies at positions 8 g .. 8 g + 7
    below ``n`` of the body loop (awake.body_id), through group g of ``out`` (POSE_ROWS): a lane past
    ``n`` works on the last body and keeps nothing, as a static body's lane keeps nothing."""
    ids = ti.Vector([0] * LANES, ti.i32)
    keep = ti.Vector([0] * LANES, ti.i32)
    v = [lanes(0.0), lanes(0.0), lanes(0.0)]
    w = [lanes(0.0), lanes(0.0), lanes(0.0)]
    x = [lanes(0.0), lanes(0.0), lanes(0.0)]
    rem = [lanes(0.0), lanes(0.0), lanes(0.0)]
    moved = [lanes(0.0), lanes(0.0), lanes(0.0)]
    damp = [lanes(0.0), lanes(0.0)]
    q = [lanes(0.0), lanes(0.0), lanes(0.0), lanes(0.0)]
    inertia = [lanes(0.0) for _ in range(9)]
    inv_inertia = [lanes(0.0) for _ in range(9)]
    for l in ti.static(range(LANES)):
        k = g * LANES + l
        i = body_id(awake, ti.min(k, n - 1))
        ids[l] = i
        keep[l] = 1 if k < n and bodies.inv_mass[i] > 0.0 else 0
        for e in ti.static(range(3)):
            v[e][l] = bodies.lin_vel[i][e]
            w[e][l] = bodies.ang_vel[i][e]
            x[e][l] = bodies.pos[i][e]
            rem[e][l] = bodies.pos_rem[i][e]
            moved[e][l] = bodies.moved[i][e]
            for c in ti.static(range(3)):
                inertia[3 * e + c][l] = bodies.inertia[i][e, c]
                inv_inertia[3 * e + c][l] = bodies.inv_inertia[i][e, c]
        for e in ti.static(range(4)):
            q[e][l] = bodies.rot[i][e]
        if ti.static(motion & DAMPING):
            damp[0][l] = bodies.damping[i][0]
            damp[1][l] = bodies.damping[i][1]
    if ti.static(motion & DAMPING):
        for e in ti.static(range(3)):
            v[e] = v[e] / (1.0 + h * damp[0])
            w[e] = w[e] / (1.0 + h * damp[1])
    dx = [h * v[e] for e in ti.static(range(3))]
    b = [dx[e] + rem[e] for e in ti.static(range(3))]
    s = [x[e] + b[e] for e in ti.static(range(3))]  # math3d.two_sum(pos, dx + pos_rem)
    b_part = [s[e] - x[e] for e in ti.static(range(3))]
    a_part = [s[e] - b_part[e] for e in ti.static(range(3))]
    err = [(x[e] - a_part[e]) + (b[e] - b_part[e]) for e in ti.static(range(3))]
    moved_after = [moved[e] + dx[e] for e in ti.static(range(3))]
    # integrate._rotate_gyroscopic
    zero = lanes(0.0)
    half_h = 0.5 * h
    l0 = _mat_vec(inertia, _quat_rotate_inv(q, w))
    w0 = _mat_vec(inv_inertia, l0)
    tol = NEWTON_TOLERANCE * NEWTON_TOLERANCE * _norm_sqr3(w0)
    wx, wy, wz = w0[0], w0[1], w0[2]  # the Newton iterate: variables carried round the loop
    active = ti.Vector([1] * LANES, ti.i32)
    for _ in range(NEWTON_STEPS):
        wn = [wx, wy, wz]
        iw = _mat_vec(inertia, wn)
        t = _mat_vec(inv_inertia, _cross(wn, iw))
        gn = [wn[e] + half_h * t[e] - w0[e] for e in ti.static(range(3))]
        active = active & (1 - ti.cast(_norm_sqr3(gn) <= tol, ti.i32))  # a NaN keeps stepping, as alone
        if active.sum() == 0:
            break
        inner = _mat_mul(_skew(wn, zero), inertia)
        skew_iw = _skew(iw, zero)
        m = _mat_mul(inv_inertia, [inner[k] - skew_iw[k] for k in ti.static(range(9))])
        jac = [IDENTITY[k] + half_h * m[k] for k in ti.static(range(9))]
        step = _mat_vec(_inverse(jac), gn)
        keep_going = active != 0
        wx = ti.select(keep_going, wx - step[0], wx)
        wy = ti.select(keep_going, wy - step[1], wy)
        wz = ti.select(keep_going, wz - step[2], wz)
    wn = [wx, wy, wz]
    rot = _quat_normalize([lanes(1.0), half_h * wn[0], half_h * wn[1], half_h * wn[2]])
    l1 = _quat_rotate_inv(rot, l0)
    q1 = _quat_normalize(_quat_mul(q, rot))
    w1 = lane_quat_rotate(q1, _mat_vec(inv_inertia, l1))
    rows = moved_after + s + err + q1 + w1 + v
    out[g] = ti.Matrix.rows(rows)
    new = out[g]
    for l in ti.static(range(LANES)):
        if keep[l]:
            i = ids[l]
            if ti.static(motion & DAMPING):
                bodies.lin_vel[i] = ti.math.vec3(new[16, l], new[17, l], new[18, l])
            bodies.moved[i] = ti.math.vec3(new[0, l], new[1, l], new[2, l])
            bodies.pos[i] = ti.math.vec3(new[3, l], new[4, l], new[5, l])
            bodies.pos_rem[i] = ti.math.vec3(new[6, l], new[7, l], new[8, l])
            bodies.rot[i] = ti.math.vec4(new[9, l], new[10, l], new[11, l], new[12, l])
            bodies.ang_vel[i] = ti.math.vec3(new[13, l], new[14, l], new[15, l])
