"""Closest points between points and segments: the geometry of rounded cores.

Spheres are points and capsules are segments with a radius, so every rounded
pair reduces to one of these queries (Ericson, Real-Time Collision Detection,
2005, sections 5.1.2 and 5.1.9). Polytope edges are segments too, which is why
the polytope routines use them for edge-edge contact points.
"""

import taichi as ti

from ..math3d import dot, quat_rotate
from .tolerances import LENGTH_EPS2, PARALLEL_EPS2

vec3 = ti.math.vec3
vec4 = ti.math.vec4


@ti.func
def core_segment(pos: vec3, rot: vec4, half_height: ti.f32):
    """World end points of a capsule's core (local z axis); a sphere passes half_height 0."""
    h = quat_rotate(rot, vec3(0.0, 0.0, half_height))
    return pos - h, pos + h


@ti.func
def closest_on_segment(p: vec3, s0: vec3, s1: vec3) -> vec3:
    """Point of segment [s0, s1] closest to p (a zero-length segment returns s0)."""
    d = s1 - s0
    dd = dot(d, d)
    t = 0.0
    if dd > LENGTH_EPS2:
        t = ti.math.clamp(dot(p - s0, d) / dd, 0.0, 1.0)
    return s0 + t * d


@ti.func
def closest_segments(p1: vec3, q1: vec3, p2: vec3, q2: vec3):
    """Closest points (c1 on [p1, q1], c2 on [p2, q2]) of two segments (Ericson 5.1.9).

    Degenerate (point) segments are handled; for parallel segments one valid
    pair is returned (s = 0 end of the first segment, clamped), which is why
    callers needing a stable two-point result clip the overlap themselves.
    """
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = dot(d1, d1)
    e = dot(d2, d2)
    f = dot(d2, r)
    s = 0.0
    t = 0.0
    if a <= LENGTH_EPS2 and e <= LENGTH_EPS2:
        s = 0.0
        t = 0.0
    elif a <= LENGTH_EPS2:
        t = ti.math.clamp(f / e, 0.0, 1.0)
    else:
        c = dot(d1, r)
        if e <= LENGTH_EPS2:
            s = ti.math.clamp(-c / a, 0.0, 1.0)
        else:
            b = dot(d1, d2)
            denom = a * e - b * b
            if denom > PARALLEL_EPS2 * a * e:
                s = ti.math.clamp((b * f - c * e) / denom, 0.0, 1.0)
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = ti.math.clamp(-c / a, 0.0, 1.0)
            elif t > 1.0:
                t = 1.0
                s = ti.math.clamp((b - c) / a, 0.0, 1.0)
    return p1 + d1 * s, p2 + d2 * t
