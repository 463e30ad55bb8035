"""Time integration: symplectic Euler with an implicit gyroscopic term, quaternion
renormalisation, and the non-finite guard.

Velocities are advanced before the contact solve (gravity, gyroscopic), positions
after it with the solved velocities. The gyroscopic term uses one Newton step of
the implicit body-frame Euler equation I (w1 - w0) + h w1 x I w1 = 0 (Catto,
"Numerical Methods", GDC 2015): explicit integration makes a spinning thin body
gain energy, the implicit step makes it lose a little instead (method.md 2.13).

The guard: a body whose velocity or pose is not finite sets an error bit and its
index (atomic min: the lowest such body is reported), so the world can restore
its last good state and say which body and stage failed, without copying state
to the host every step.
"""


import taichi as ti

from .math3d import any_nonfinite3, quat_mul, quat_normalize, quat_rotate, quat_rotate_inv, quat_to_mat

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3

ERR_VELOCITY = 1
ERR_POSE = 2
BIG = 2**30


@ti.data_oriented
class ErrorFlags:
    def __init__(self):
        self.flags = ti.field(ti.i32, ())
        self.body = ti.field(ti.i32, ())

    def clear(self):
        self.flags[None] = 0
        self.body[None] = BIG


@ti.func
def _skew(v: vec3) -> mat3:
    return mat3(0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0)


@ti.kernel
def integrate_velocities(bodies: ti.template(), gravity: vec3, h: ti.f32, gyroscopic: ti.template()):
    for i in range(bodies.count[None]):
        if bodies.inv_mass[i] > 0.0:
            bodies.lin_vel[i] += gravity * h
            q = bodies.rot[i]
            r = quat_to_mat(q)
            if ti.static(gyroscopic):
                inertia = bodies.inertia[i]
                w0 = quat_rotate_inv(q, bodies.ang_vel[i])
                f = h * w0.cross(inertia @ w0)
                jac = inertia + h * (_skew(w0) @ inertia - _skew(inertia @ w0))
                w1 = w0 - jac.inverse() @ f
                bodies.ang_vel[i] = quat_rotate(q, w1)
            bodies.inv_inertia_world[i] = r @ bodies.inv_inertia[i] @ r.transpose()


@ti.kernel
def integrate_positions(bodies: ti.template(), h: ti.f32, err: ti.template()):
    for i in range(bodies.count[None]):
        if bodies.inv_mass[i] > 0.0:
            v = bodies.lin_vel[i]
            w = bodies.ang_vel[i]
            if any_nonfinite3(v) or any_nonfinite3(w):
                ti.atomic_or(err.flags[None], ERR_VELOCITY)
                ti.atomic_min(err.body[None], i)
            x = bodies.pos[i] + h * v
            q = bodies.rot[i]
            q = quat_normalize(q + 0.5 * h * quat_mul(vec4(0.0, w[0], w[1], w[2]), q))
            if any_nonfinite3(x) or any_nonfinite3(vec3(q[1], q[2], q[3])) or not (ti.abs(q[0]) <= 1.0):
                ti.atomic_or(err.flags[None], ERR_POSE)
                ti.atomic_min(err.body[None], i)
            bodies.pos[i] = x
            bodies.rot[i] = q
