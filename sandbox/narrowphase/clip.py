"""Face contacts between polytopes: the incident face clipped by the reference face.

Once SAT has chosen a reference face (on A or B), the incident face is the
face of the other shape whose normal is most anti-parallel to it. The contact
patch is the incident polygon clipped by the side planes of the reference
face, the result Sutherland-Hodgman clipping would give (Sutherland and
Hodgman, "Reentrant polygon clipping", CACM 1974). Its vertices are of three
kinds, which are enumerated directly instead of clipping a buffer:

* incident vertices inside every side plane;
* crossings of an incident edge with a side plane, inside the other planes;
* reference-face corners whose normal line pierces the incident polygon.

Candidates below the reference plane + margin stream into ``reduce.Reducer``
(see there for why there is no buffer, and so no capacity limit). Geometry is
in the reference shape's local frame, so the reference face is read from the
pool untransformed; corners are tested in the incident shape's frame for the
same reason.

A point within CLIP_EPS of a side plane (or of an incident edge) counts as on
it, and a crossing is only made when the edge clearly crosses. So two faces
with coinciding borders (a box on an equal box) give exactly their four
vertices instead of vertices plus near-duplicate crossings whose ids would
flicker with round-off.

Feature ids: ``kind << 28 | ref_face << 21 | inc_face << 14 | code``, kind 0
when the reference face is on A and 1 when on B (faces are local indices, at
most 124 for a 64-vertex hull, so 7 bits each); code is ``j`` for incident
vertex j, ``1 << 12 | j << 6 | k`` for incident edge j (from loop vertex j to
j + 1) crossing side plane k (reference edge k to k + 1), and ``2 << 12 | k``
for reference corner k (loop positions, < 64). If no candidate lies below the
margin although SAT found the faces within it (the faces do not overlap,
e.g. a vertex touching a face near its border), one point is made at the
incident shape's support vertex instead, id
``3 << 28 | ref_on_b << 27 | ref_face << 8 | vertex`` (against a mesh
triangle only if that vertex lies in the reference face's prism: a triangle
pushes only over itself).
"""

import taichi as ti

from ..math3d import dot, quat_conj, quat_rotate
from ..shapes import TRIANGLE
from .manifold import ShapePose, manifold_add
from .reduce import REDUCE_PASSES, reducer_finish, reducer_needs_pass, reducer_new, reducer_visit
from .tolerances import CLIP_EPS, CORNER_MIN_COS, INCIDENT_TIE_COS

vec3 = ti.math.vec3
vec4 = ti.math.vec4

EDGE_CROSSING = 1 << 12
REF_CORNER = 2 << 12
FALLBACK_KIND = 3
CANDIDATE_BUFFER = 16
"""Clip candidates kept in registers/local memory (a box-box patch has at most 8)."""


@ti.func
def _xf(q: vec4, p: vec3, v: vec3) -> vec3:
    return p + quat_rotate(q, v)


@ti.func
def _side_distance(pool: ti.template(), loop_start: ti.i32, loop_count: ti.i32, k: ti.i32, normal: vec3,
                   x: vec3) -> ti.f32:
    """Signed distance [m] of x from side plane k of a face (> 0 outside); loops are CCW from
    outside. The planes are precomputed per loop entry (``PolytopePool.side``)."""
    s = pool.side[loop_start + k]
    return s[0] * x[0] + s[1] * x[1] + s[2] * x[2] - s[3]


@ti.func
def _inside_ref(pool: ti.template(), ls: ti.i32, lc: ti.i32, normal: vec3, x: vec3, skip: ti.i32) -> ti.i32:
    inside = 1
    for k in range(lc):
        if k != skip and _side_distance(pool, ls, lc, k, normal, x) > CLIP_EPS:
            inside = 0
    return inside


@ti.func
def _candidates(pool: ti.template(), r: ti.template(), pass_index: ti.i32, buffered: ti.template(),
                buf_p: ti.template(), buf_s: ti.template(), buf_id: ti.template(), q_ir: vec4, p_ir: vec3,
                q_ri: vec4, p_ri: vec3, n_r: vec3, o_r: ti.f32, rls: ti.i32, rlc: ti.i32, n_i: vec3, o_i: ti.f32,
                n_r_i: vec3, ils: ti.i32, ilc: ti.i32, header: ti.i32, margin: ti.f32) -> ti.i32:
    """Enumerate the clip candidates below the margin, in their fixed order: into the reducer's
    pass ``pass_index`` (streaming), or into the first CANDIDATE_BUFFER rows of the buffer.
    Returns how many there are."""
    found = 0
    total = ilc + ilc * rlc + rlc
    # the crossings run j-major: keep incident edge j's end points between candidates
    edge_j = -1
    x0 = vec3(0.0, 0.0, 0.0)
    x1 = vec3(0.0, 0.0, 0.0)
    for c in range(total):
        valid = 0
        x = vec3(0.0, 0.0, 0.0)  # candidate on the incident face, reference frame
        code = 0
        if c < ilc:  # incident vertex
            x = _xf(q_ir, p_ir, pool.vert[pool.loop[ils + c]])
            valid = _inside_ref(pool, rls, rlc, n_r, x, -1)
            code = c
        elif c < ilc + ilc * rlc:  # incident edge j crossing side plane k
            j = (c - ilc) // rlc
            k = (c - ilc) % rlc
            if j != edge_j:
                edge_j = j
                x0 = _xf(q_ir, p_ir, pool.vert[pool.loop[ils + j]])
                x1 = _xf(q_ir, p_ir, pool.vert[pool.loop[ils + (j + 1) % ilc]])
            d0 = _side_distance(pool, rls, rlc, k, n_r, x0)
            d1 = _side_distance(pool, rls, rlc, k, n_r, x1)
            if ti.min(d0, d1) < -CLIP_EPS and ti.max(d0, d1) > CLIP_EPS:
                x = x0 + (d0 / (d0 - d1)) * (x1 - x0)
                valid = _inside_ref(pool, rls, rlc, n_r, x, k)
                code = EDGE_CROSSING | (j << 6) | k
        else:  # reference corner k projected along n_r onto the incident plane
            k = c - ilc - ilc * rlc
            v = pool.vert[pool.loop[rls + k]]
            v_i = _xf(q_ri, p_ri, v)
            den = dot(n_i, n_r_i)
            if den < -CORNER_MIN_COS:
                t = (o_i - dot(n_i, v_i)) / den
                x_i = v_i + n_r_i * t
                valid = 1
                for e in range(ilc):
                    if _side_distance(pool, ils, ilc, e, n_i, x_i) > -CLIP_EPS:
                        valid = 0
                x = v + n_r * t
                code = REF_CORNER | k
        sep = dot(n_r, x) - o_r
        if valid and sep < margin:
            y = x - n_r * (0.5 * sep)
            if ti.static(buffered):
                if found < CANDIDATE_BUFFER:
                    for cc in ti.static(range(3)):
                        buf_p[found, cc] = y[cc]
                    buf_s[found] = sep
                    buf_id[found] = header | code
            else:
                reducer_visit(r, pass_index, y, sep, header | code, n_r)
            found += 1
    return found


@ti.func
def face_contact(pool: ti.template(), m: ti.template(), a: ShapePose, b: ShapePose, q_ba: vec4, p_ba: vec3,
                 ref_on_b: ti.i32, ref_face: ti.i32, support_vert: ti.i32, margin: ti.f32):
    """Fill ``m`` with the clipped face contact; ref_face is local to the reference shape."""
    q_ab = quat_conj(q_ba)
    p_ab = -quat_rotate(q_ab, p_ba)
    ref_poly, inc_poly = a.poly, b.poly
    q_ir, p_ir, q_ri, p_ri = q_ba, p_ba, q_ab, p_ab  # incident -> reference frame and back
    rot_w, pos_w = a.rot, a.pos  # world pose of the reference frame
    if ref_on_b:
        ref_poly, inc_poly = b.poly, a.poly
        q_ir, p_ir, q_ri, p_ri = q_ab, p_ab, q_ba, p_ba
        rot_w, pos_w = b.rot, b.pos

    rf = pool.face_start[ref_poly] + ref_face
    n_r = pool.face_normal[rf]
    o_r = pool.face_offset[rf]
    rls = pool.face_loop_start[rf]
    rlc = pool.face_loop_count[rf]

    # incident face: most anti-parallel; near ties go to the lower index (stable ids)
    n_r_i = quat_rotate(q_ri, n_r)
    fs_i = pool.face_start[inc_poly]
    inc = 0
    best = 2.0
    for j in range(pool.face_count[inc_poly]):
        d = dot(pool.face_normal[fs_i + j], n_r_i)
        if d < best - INCIDENT_TIE_COS:
            best = d
            inc = j
    fi = fs_i + inc
    n_i = pool.face_normal[fi]
    o_i = pool.face_offset[fi]
    ils = pool.face_loop_start[fi]
    ilc = pool.face_loop_count[fi]
    header = (ref_on_b << 28) | (ref_face << 21) | (inc << 14)

    r = reducer_new()
    # Candidates are made once into a small buffer and the reducer's passes read it; only a
    # face pair with more than CANDIDATE_BUFFER candidates (large hull faces) regenerates
    # them per pass (the streaming scheme of reduce.py). Same candidates, same order.
    buf_p = ti.Matrix.zero(ti.f32, CANDIDATE_BUFFER, 3)
    buf_s = ti.Vector.zero(ti.f32, CANDIDATE_BUFFER)
    buf_id = ti.Vector.zero(ti.i32, CANDIDATE_BUFFER)
    found = _candidates(pool, r, 0, True, buf_p, buf_s, buf_id, q_ir, p_ir, q_ri, p_ri, n_r, o_r, rls, rlc, n_i, o_i,
                        n_r_i, ils, ilc, header, margin)
    if found <= CANDIDATE_BUFFER:
        for pass_index in range(REDUCE_PASSES):
            if reducer_needs_pass(r, pass_index):
                for i in range(found):
                    reducer_visit(r, pass_index, vec3(buf_p[i, 0], buf_p[i, 1], buf_p[i, 2]), buf_s[i], buf_id[i], n_r)
    else:
        for pass_index in range(REDUCE_PASSES):
            if reducer_needs_pass(r, pass_index):
                _candidates(pool, r, pass_index, False, buf_p, buf_s, buf_id, q_ir, p_ir, q_ri, p_ri, n_r, o_r, rls,
                            rlc, n_i, o_i, n_r_i, ils, ilc, header, margin)

    n_w = quat_rotate(rot_w, n_r)
    m.normal = n_w
    m.normal_on_b = ref_on_b
    if ref_on_b:
        m.normal = -n_w
    if r.count > 0:
        reducer_finish(r, m, rot_w, pos_w)
    elif support_vert >= 0:
        x = _xf(q_ir, p_ir, pool.vert[pool.vert_start[inc_poly] + support_vert])
        sep = dot(n_r, x) - o_r
        # a mesh triangle pushes only over (or at) itself: the fallback must lie in the reference prism
        over_ref = 1
        if b.kind == TRIANGLE:
            over_ref = _inside_ref(pool, rls, rlc, n_r, x, -1)
        if sep < margin and over_ref:
            manifold_add(m, _xf(rot_w, pos_w, x - n_r * (0.5 * sep)), sep,
                         (FALLBACK_KIND << 28) | (ref_on_b << 27) | (ref_face << 8) | support_vert)
