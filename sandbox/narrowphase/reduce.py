"""Reduce a stream of candidate contact points to the four that best hold the shapes.

Clipping a face against a face, or a hull against a plane, can give many
points; the manifold carries four. The choice is the usual one (Bullet's
``sortCachedPoints``, Jolt's ``PruneContactPoints``, Box2D's manifold
reduction): keep the deepest point (it carries the load), then the point
farthest from it in the contact plane (the longest lever arm), then the point
that spans the largest triangle with those two, then the point that adds the
most area outside that triangle. The four points bound almost all of the
patch, so the solver can resist any torque the full patch could.

One change to that rule: each later pass divides a candidate's lever arm or area
by 1 + g / ``REDUCE_GAP_LENGTH``, g its gap above the deepest point (above
touching, when the deepest touches), so that on a tilted face a corner about to
touch beats one high up in the speculative margin, which cannot carry load within
the step (why, measured: tolerances.REDUCE_GAP_LENGTH).

Why a stream and not a buffer: local arrays in Taichi functions make the
compiler's IR passes grow with the square of their total size (measured with
Taichi's advanced optimisation on: a pair of 64-point clip buffers cost
seconds of compile time per inlined copy), and on a GPU they live in slow
local memory. The producers (``clip.py``,
``polytope.collide_plane_polytope``) therefore regenerate their candidates in
up to four passes, and ``reducer_visit`` keeps only what each pass needs.
Pass 0 counts and stores the first four; when there are at most four, that is
the result and no further pass runs (the common resting case).

The selection depends only on the candidates; exact ties go to the earlier
candidate, and producers enumerate candidates in a fixed order, so the result
is deterministic. Up to four candidates come out in candidate order; a
reduced set comes out as deepest, farthest, third, fourth.
"""

import taichi as ti

from ..math3d import cross, dot, quat_rotate
from .manifold import MAX_POINTS, manifold_add
from .tolerances import REDUCE_AREA_EPS, REDUCE_GAP_LENGTH

vec3 = ti.math.vec3
vec4 = ti.math.vec4
ivec4 = ti.types.vector(4, ti.i32)
mat43 = ti.types.matrix(4, 3, ti.f32)

REDUCE_PASSES = 4


@ti.dataclass
class Reducer:
    count: ti.i32  # candidates seen in pass 0
    pts: mat43  # rows 0-3: the first four candidates (pass 0), then replaced by the chosen ones
    sep: vec4
    ids: ivec4
    chosen: mat43  # row k: point chosen by pass k
    chosen_sep: vec4
    chosen_id: ivec4
    score: vec4  # best criterion value of pass k so far
    sign: ti.f32  # orientation of the triangle of passes 0-2 about the normal


@ti.func
def reducer_new() -> Reducer:
    return Reducer(count=0, score=vec4(3.0e38, REDUCE_AREA_EPS, REDUCE_AREA_EPS, REDUCE_AREA_EPS), sign=1.0)


@ti.func
def reducer_needs_pass(r: ti.template(), pass_index: ti.i32) -> ti.i32:
    """Pass 0 always runs; the others only when there are more than four candidates."""
    return pass_index == 0 or r.count > MAX_POINTS


@ti.func
def _row(mat: ti.template(), k: ti.template()) -> vec3:
    return vec3(mat[k, 0], mat[k, 1], mat[k, 2])


@ti.func
def _area(p0: vec3, p1: vec3, p: vec3, normal: vec3) -> ti.f32:
    """Twice the signed area of triangle (p0, p1, p) seen along ``normal``."""
    return dot(cross(p1 - p0, p - p0), normal)


@ti.func
def _choose(r: ti.template(), k: ti.template(), p: vec3, sep: ti.f32, feature: ti.i32, score: ti.f32):
    r.score[k] = score
    for c in ti.static(range(3)):
        r.chosen[k, c] = p[c]
    r.chosen_sep[k] = sep
    r.chosen_id[k] = feature


@ti.func
def _nearness(r: ti.template(), sep: ti.f32) -> ti.f32:
    """1 for a candidate as deep as the deepest point (or touching), falling with its gap above."""
    gap = ti.max(sep - ti.max(r.chosen_sep[0], 0.0), 0.0)
    return 1.0 / (1.0 + gap / REDUCE_GAP_LENGTH)


@ti.func
def reducer_visit(r: ti.template(), pass_index: ti.i32, p: vec3, sep: ti.f32, feature: ti.i32, normal: vec3):
    """Feed one candidate (point, separation, feature id) of pass ``pass_index``."""
    if pass_index == 0:
        for k in ti.static(range(MAX_POINTS)):
            if r.count == k:
                for c in ti.static(range(3)):
                    r.pts[k, c] = p[c]
                r.sep[k] = sep
                r.ids[k] = feature
        r.count += 1
        if sep < r.score[0]:  # deepest
            _choose(r, 0, p, sep, feature, sep)
    elif pass_index == 1:  # farthest from the deepest, in the contact plane
        d = p - _row(r.chosen, 0)
        d -= normal * dot(d, normal)
        score = dot(d, d) * _nearness(r, sep)
        if score > r.score[1]:
            _choose(r, 1, p, sep, feature, score)
    elif pass_index == 2:  # largest triangle with those two, either side
        s = _area(_row(r.chosen, 0), _row(r.chosen, 1), p, normal)
        score = ti.abs(s) * _nearness(r, sep)
        if r.score[1] > REDUCE_AREA_EPS and score > r.score[2]:
            _choose(r, 2, p, sep, feature, score)
            r.sign = 1.0 if s > 0.0 else -1.0
    else:  # most area added outside that triangle
        if r.score[2] > REDUCE_AREA_EPS:
            p0 = _row(r.chosen, 0)
            p1 = _row(r.chosen, 1)
            p2 = _row(r.chosen, 2)
            added = ti.max(-r.sign * _area(p0, p1, p, normal),
                           ti.max(-r.sign * _area(p1, p2, p, normal), -r.sign * _area(p2, p0, p, normal)))
            added *= _nearness(r, sep)
            if added > r.score[3]:
                _choose(r, 3, p, sep, feature, added)


@ti.func
def reducer_finish(r: ti.template(), m: ti.template(), rot: vec4, pos: vec3):
    """Append the kept points to manifold ``m``; points were given in the frame (rot, pos)."""
    if r.count <= MAX_POINTS:
        for k in ti.static(range(MAX_POINTS)):
            if k < r.count:
                manifold_add(m, pos + quat_rotate(rot, _row(r.pts, k)), r.sep[k], r.ids[k])
    else:
        for k in ti.static(range(MAX_POINTS)):
            # pass 0 always chose; later passes only when their criterion beat the epsilon
            if ti.static(k == 0) or r.score[k] > REDUCE_AREA_EPS:
                manifold_add(m, pos + quat_rotate(rot, _row(r.chosen, k)), r.chosen_sep[k], r.chosen_id[k])
