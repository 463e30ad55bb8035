"""Time integration: symplectic Euler for translation, an energy- and momentum-
conserving rotation update, quaternion renormalisation, and the non-finite guard.

Within each substep, velocities are advanced by gravity before the contact
sweep and positions after it with the solved velocities (symplectic Euler). Rotation uses the implicit midpoint rule on the
body-frame angular momentum with the Cayley map (method.md 2.13 asks for an
implicit gyroscopic term; this one is also exactly conservative). With L the
body-frame momentum at the start of the rotation and w = I^-1 (L + L') / 2 the
midpoint angular velocity, the step rotates the body by Q = cay(h w) (the unit
quaternion (1, h w / 2) normalised) and sets L' = Q^T L. Then

* world momentum R' L' = R Q Q^T L = R L is unchanged (torque-free), and
* the Cayley identity L' - L = -(h/2) w x (L + L') is orthogonal to w, so the
  energy 1/2 L.I^-1 L is unchanged too: a spinning thin body cannot gain energy.

w is found by Newton's method on the implicit midpoint equation; with an inexact
w the rotation is still exact (momentum kept), only the energy error grows.
Contact and gravity impulses act before, in the solver.

The guard: a body whose velocity or pose is not finite sets an error bit and its
index (atomic min: the lowest such body is reported), so the world can restore
its last good state and say which body and stage failed, without copying state
to the host every step.
"""

import taichi as ti

from .awake import body_id, body_total
from .backend import serialize_light_loops
from .math3d import (any_nonfinite3, cross, mat_mul, mat_vec, quat_mul, quat_normalize, quat_rotate, quat_rotate_inv,
                     two_sum)

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3

ERR_VELOCITY = 1
ERR_POSE = 2
ERR_BOUNDS = 4  # broadphase: a body's bounds span too many grid cells (broadphase.MAX_SPAN_CELLS)
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
def clear_error_flags(errors: ti.template()):
    """``ErrorFlags.clear`` inside a kernel."""
    errors.flags[None] = 0
    errors.body[None] = BIG


GYROSCOPIC, DAMPING = 1, 2
"""Bits of the ``motion`` switch of the position update (effects.py compiles each in only when some
body needs it): the implicit gyroscopic solve, and linear / angular damping."""


def motion_switch(effects) -> int:
    """The position update's ``motion`` bits for an effects.CompiledEffects."""
    return (GYROSCOPIC if effects.gyroscopic else 0) | (DAMPING if effects.damping else 0)


NEWTON_STEPS = 3
"""Newton steps for the midpoint angular velocity; quadratic convergence even for thin rods,
whose tiny axial inertia makes a fixed-point iteration diverge (measured: +15 % energy on a
1:40 rod at 30 rad/s, 240 Hz substeps, with two fixed-point sweeps)."""

NEWTON_TOLERANCE = 2.0**-22
"""[1] Newton stops once |G(w)| <= this x |w0|: a few float32 ulps, so a further step
could not change w. A resting or slowly turning body needs one step, not NEWTON_STEPS
(the position update is ~15 % of a 1000-box pile's substep)."""


@ti.func
def apply_gravity(bodies: ti.template(), gravity: vec3, h: ti.f32, i: ti.i32):
    if bodies.inv_mass[i] > 0.0:
        bodies.lin_vel[i] += gravity * h


@ti.func
def gravity_loop(bodies: ti.template(), awake: ti.template(), gravity: vec3, h: ti.f32, active: ti.i32):
    """``awake`` (awake.py): every body, or the awake ones of a sleeping world."""
    for k in range(body_total(bodies, awake) * active):  # active = 0: skipped, still a top-level loop
        apply_gravity(bodies, gravity, h, body_id(awake, k))


@ti.kernel
def integrate_velocities(bodies: ti.template(), awake: ti.template(), gravity: vec3, h: ti.f32):
    gravity_loop(bodies, awake, gravity, h, 1)


@ti.func
def _skew(v: vec3) -> mat3:
    return mat3(0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0)


@ti.func
def rotate_free(q: vec4, omega: vec3, inertia: ti.template(), inv_inertia: ti.template(), h: ti.f32,
                motion: ti.template()):
    """Midpoint/Cayley rotation step (module docstring): returns the new orientation
    and the new world angular velocity. The midpoint w solves
    G(w) = I w + (h/2) w x (I w) - L = 0 (the implicit midpoint rule for Euler's
    equations, equivalent to L' = cay(-h w) L with w = I^-1 (L + L') / 2).

    Without the GYROSCOPIC bit in ``motion`` (effects.py: no dynamic body of the world has an anisotropic
    inertia): L = I w is parallel to w, the world angular velocity stays as it is, and the
    rotation is the Cayley step about it, with no Newton solve and no inertia products."""
    q1 = q
    w1 = omega
    if ti.static(not motion & GYROSCOPIC):
        wb = quat_rotate_inv(q, omega)
        q1 = quat_normalize(quat_mul(q, quat_normalize(vec4(1.0, 0.5 * h * wb[0], 0.5 * h * wb[1], 0.5 * h * wb[2]))))
    else:
        q1, w1 = _rotate_gyroscopic(q, omega, inertia, inv_inertia, h)
    return q1, w1


@ti.func
def _rotate_gyroscopic(q: vec4, omega: vec3, inertia: ti.template(), inv_inertia: ti.template(), h: ti.f32):
    l0 = mat_vec(inertia, quat_rotate_inv(q, omega))
    w0 = mat_vec(inv_inertia, l0)
    w = w0
    tol = NEWTON_TOLERANCE * NEWTON_TOLERANCE * w0.norm_sqr()
    for _ in range(NEWTON_STEPS):
        # G premultiplied by I^-1 so the system is O(1) whatever the body's size: a 1 mm
        # cube's inertia (~1e-13 kg m^2) would underflow a float32 determinant
        iw = mat_vec(inertia, w)
        g = w + 0.5 * h * mat_vec(inv_inertia, cross(w, iw)) - w0
        if g.norm_sqr() <= tol:
            break
        jac = ti.Matrix.identity(ti.f32, 3) + 0.5 * h * mat_mul(inv_inertia, mat_mul(_skew(w), inertia) - _skew(iw))
        w -= mat_vec(jac.inverse(), g)
    step = quat_normalize(vec4(1.0, 0.5 * h * w[0], 0.5 * h * w[1], 0.5 * h * w[2]))
    l1 = quat_rotate_inv(step, l0)
    q1 = quat_normalize(quat_mul(q, step))
    return q1, quat_rotate(q1, mat_vec(inv_inertia, l1))


@ti.func
def nonfinite_pose(x: vec3, q: vec4) -> ti.i32:
    """1 when a position or an orientation holds a NaN or an infinity (a unit quaternion's real
    part is in [-1, 1]; a NaN fails that comparison)."""
    return any_nonfinite3(x) or any_nonfinite3(vec3(q[1], q[2], q[3])) or not (ti.abs(q[0]) <= 1.0)


@ti.func
def check_bodies_loops(bodies: ti.template(), err: ti.template(), awake: ti.template()):
    """Flags a body whose velocity or pose is not finite, once per step, at its end. Within a step
    every write to a body's velocity and pose adds to the old value (sweeps, gravity, damping, the
    compensated position sum, the normalised rotation), and IEEE arithmetic keeps a NaN or an
    infinity through that, so this one check finds whatever a check in every position update
    would, the same body included. There it cost most of a CUDA substep: with its two guarded
    atomics the position update took ~1 ms per launch on an H200 whatever the body count, 88 us
    without them (benchmarks/position_update_probe.py, docs/bench.md)."""
    n = body_total(bodies, awake)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(awake, k)
        if bodies.inv_mass[i] > 0.0:
            bad_velocity = any_nonfinite3(bodies.lin_vel[i]) or any_nonfinite3(bodies.ang_vel[i])
            bad_pose = nonfinite_pose(bodies.pos[i], bodies.rot[i])
            if bad_velocity or bad_pose:
                ti.atomic_or(err.flags[None], ERR_VELOCITY if bad_velocity else ERR_POSE)
                ti.atomic_min(err.body[None], i)


@ti.kernel
def check_bodies(bodies: ti.template(), err: ti.template(), awake: ti.template()):
    check_bodies_loops(bodies, err, awake)


@ti.func
def advance_pose(bodies: ti.template(), motion: ti.template(), h: ti.f32, i: ti.i32):
    """Body i's position and orientation over ``h`` with its solved velocities.

    With the DAMPING bit, the velocities are damped first, implicitly (``v / (1 + h c)``, Box2D's
    and Rapier's form: it never reverses a velocity, however large ``h c``); the damped
    velocity moves the body and is what the next sweeps see."""
    if bodies.inv_mass[i] > 0.0:
        v = bodies.lin_vel[i]
        w = bodies.ang_vel[i]
        if ti.static(motion & DAMPING):
            c = bodies.damping[i]
            v = v / (1.0 + h * c[0])
            w = w / (1.0 + h * c[1])
            bodies.lin_vel[i] = v
        dx = h * v
        x, rem = two_sum(bodies.pos[i], dx + bodies.pos_rem[i])
        bodies.moved[i] += dx
        q, w1 = rotate_free(bodies.rot[i], w, bodies.inertia[i], bodies.inv_inertia[i], h, motion)
        bodies.pos[i] = x
        bodies.pos_rem[i] = rem
        bodies.rot[i] = q
        bodies.ang_vel[i] = w1


@ti.func
def positions_loop(bodies: ti.template(), awake: ti.template(), motion: ti.template(), h: ti.f32):
    for k in range(body_total(bodies, awake)):
        advance_pose(bodies, motion, h, body_id(awake, k))


@ti.kernel
def integrate_positions(bodies: ti.template(), awake: ti.template(), motion: ti.template(), h: ti.f32):
    positions_loop(bodies, awake, motion, h)
