"""Quaternion (w, x, y, z) and small 3x3 helpers for Taichi kernels, nothing else.

``cross``, ``dot``, ``norm``, ``mat_vec`` and ``mat_mul`` write out what Taichi's
``a.cross(b)``, ``a.dot(b)``, ``v.norm()`` and ``m @ x`` compute, operation for operation in the
same order, so the bits are the same (the state hashes did not move); the engine's kernels use
them for every product of 3-vectors and 3x3 matrices (a 4-vector's norm keeps Taichi's). Why:
Taichi 1.7's frontend turns every kernel's Python AST into IR in every process (its offline cache
is keyed on that IR) and transforms a called function's body once per call site; Taichi's
generic matrix helpers run shape checks and static loops each time, ~2 ms per ``cross`` or ``dot``
and ~20 ms per ``@`` on the 2-core VM. Written out, a first step makes 13 % fewer Python calls
(``python benchmarks/first_step.py --split``; docs/bench.md, "Tenth pass")."""


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
def cross(a: vec3, b: vec3) -> vec3:
    """``a.cross(b)``, written out (module docstring)."""
    return vec3(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@ti.func
def dot(a: vec3, b: vec3) -> ti.f32:
    """``a.dot(b)``, written out (module docstring): Taichi sums the products left to right."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@ti.func
def norm(v: vec3) -> ti.f32:
    """``v.norm()``, written out (module docstring): Taichi adds its ``eps`` argument, 0.0."""
    return ti.sqrt(dot(v, v) + 0.0)


@ti.func
def mat_vec(m: mat3, v: vec3) -> vec3:
    """``m @ v``, written out (module docstring): Taichi starts each sum from
    ``m[0, 0] v[0] 0`` (a zero of the product's type) and adds the products left to right."""
    zero = m[0, 0] * v[0] * 0
    return vec3(((zero + m[0, 0] * v[0]) + m[0, 1] * v[1]) + m[0, 2] * v[2],
                ((zero + m[1, 0] * v[0]) + m[1, 1] * v[1]) + m[1, 2] * v[2],
                ((zero + m[2, 0] * v[0]) + m[2, 1] * v[1]) + m[2, 2] * v[2])


@ti.func
def mat_mul(a: mat3, b: mat3) -> mat3:
    """``a @ b``, written out as ``mat_vec`` is."""
    zero = a[0, 0] * b[0, 0] * 0
    return mat3(((zero + a[0, 0] * b[0, 0]) + a[0, 1] * b[1, 0]) + a[0, 2] * b[2, 0],
                ((zero + a[0, 0] * b[0, 1]) + a[0, 1] * b[1, 1]) + a[0, 2] * b[2, 1],
                ((zero + a[0, 0] * b[0, 2]) + a[0, 1] * b[1, 2]) + a[0, 2] * b[2, 2],
                ((zero + a[1, 0] * b[0, 0]) + a[1, 1] * b[1, 0]) + a[1, 2] * b[2, 0],
                ((zero + a[1, 0] * b[0, 1]) + a[1, 1] * b[1, 1]) + a[1, 2] * b[2, 1],
                ((zero + a[1, 0] * b[0, 2]) + a[1, 1] * b[1, 2]) + a[1, 2] * b[2, 2],
                ((zero + a[2, 0] * b[0, 0]) + a[2, 1] * b[1, 0]) + a[2, 2] * b[2, 0],
                ((zero + a[2, 0] * b[0, 1]) + a[2, 1] * b[1, 1]) + a[2, 2] * b[2, 1],
                ((zero + a[2, 0] * b[0, 2]) + a[2, 1] * b[1, 2]) + a[2, 2] * b[2, 2])


@ti.func
def quat_rotate(q: vec4, v: vec3) -> vec3:
    """Rotate v by unit quaternion q (w, x, y, z): v + w t + u x t with t = 2 u x v, u = (x, y, z),
    both cross products written out here: the step's kernels reach this function from ~60 call
    sites, and a call fewer each saves ~130 000 of the ~5.4 million Python calls of stack_20's first
    step (module docstring)."""
    x, y, z = q[1], q[2], q[3]
    t = 2.0 * vec3(y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0])
    return v + q[0] * t + vec3(y * t[2] - z * t[1], z * t[0] - x * t[2], x * t[1] - y * t[0])


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
