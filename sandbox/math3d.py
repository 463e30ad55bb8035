"""Quaternion (w, x, y, z) and small 3x3 helpers for Taichi kernels, nothing else."""


import taichi as ti

vec3 = ti.math.vec3
vec4 = ti.math.vec4
mat3 = ti.math.mat3


@ti.func
def two_sum(a: vec3, b: vec3):
    """(s, e) with s = fl(a + b) and s + e = a + b exactly (Knuth's TwoSum, any magnitudes;
    needs IEEE arithmetic, which backend.py keeps by turning fast_math off)."""
    s = a + b
    b_part = s - a
    a_part = s - b_part
    return s, (a - a_part) + (b - b_part)


@ti.func
def quat_mul(a: vec4, b: vec4) -> vec4:
    return vec4(
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    )


@ti.func
def quat_conj(q: vec4) -> vec4:
    return vec4(q[0], -q[1], -q[2], -q[3])


@ti.func
def quat_rotate(q: vec4, v: vec3) -> vec3:
    """Rotate v by unit quaternion q (w, x, y, z)."""
    u = vec3(q[1], q[2], q[3])
    t = 2.0 * u.cross(v)
    return v + q[0] * t + u.cross(t)


@ti.func
def quat_rotate_inv(q: vec4, v: vec3) -> vec3:
    return quat_rotate(quat_conj(q), v)


@ti.func
def quat_to_mat(q: vec4) -> mat3:
    w, x, y, z = q[0], q[1], q[2], q[3]
    return mat3(
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    )


@ti.func
def quat_normalize(q: vec4) -> vec4:
    return q / q.norm()


@ti.func
def any_nonfinite3(v: vec3) -> ti.i32:
    bad = 0
    for k in ti.static(range(3)):
        if not (ti.abs(v[k]) < 3.0e38):  # false for nan and inf
            bad = 1
    return bad


@ti.func
def plane_basis(n: vec3):
    """Deterministic tangent pair (t1, t2) orthonormal to unit n (Frisvad/Duff et al.)."""
    s = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    t1 = vec3(1.0 + s * n[0] * n[0] * a, s * b, -s * n[0])
    t2 = vec3(b, s + n[1] * n[1] * a, -n[1])
    return t1, t2
