"""Separating-axis queries between two polytopes (box, hull, mesh triangle).

Follows D. Gregorius, "The Separating Axis Test between Convex Polyhedra",
GDC 2013: the candidate axes are the face normals of both shapes and the cross
products of edge pairs; an edge pair is tested only if the arcs of the two
edges on the Gauss map intersect (the pair spans a face of the Minkowski
difference). Every other edge pair cannot be the minimal axis, and the test
is a few dot products, which keeps 64-vertex hulls (up to ~186 edges each)
affordable. For such a Minkowski pair both edges are supporting features, so
the separation along the axis is simply the distance between the edge lines.

Everything is computed in the local frame of shape A: A's vertices and
normals are read from the pool untouched and only B's data is rotated
(``q_ba``, ``p_ba`` map B-local to A-local).

One-sided triangles (always shape B, because the kind order puts triangles
last). A mesh triangle may only push the other shape towards its front side.
The queries therefore report two maxima: over *all* axes (used to decide
whether the shapes are apart, which any axis may prove) and over *allowed*
axes (used to build the contact):

* a face of A is allowed if pushing A along minus its normal moves A to the
  triangle's front (cosine > FRONT_MIN_COS);
* of the triangle's two faces only face 0 (front) is allowed;
* triangle edges are never allowed: without mesh adjacency a seam between
  two coplanar triangles cannot be told from a boundary edge, and an edge
  axis at a seam tilts the normal of a body resting on a flat mesh (the
  "internal edge" or ghost-collision problem). They still count for the
  apartness test; their Gauss-map arc is the half circle from the front normal
  n through the edge's outward in-plane direction m to -n (the two face
  normals are antipodal, so Gregorius' arc test, which needs arcs below 180
  degrees, is replaced by an explicit half-circle test).

See ``polytope.collide_polytope_polytope`` for how the two maxima combine.
"""

import taichi as ti

from ..math3d import cross, dot, norm, quat_conj, quat_rotate
from .tolerances import EDGE_PARALLEL_SIN, FRONT_MIN_COS, NO_AXIS

vec3 = ti.math.vec3
vec4 = ti.math.vec4


@ti.func
def to_a(q_ba: vec4, p_ba: vec3, v: vec3) -> vec3:
    """A B-local point expressed in A's frame."""
    return p_ba + quat_rotate(q_ba, v)


@ti.func
def face_query_a(pool: ti.template(), pa: ti.i32, pb: ti.i32, q_ba: vec4, p_ba: vec3,
                 tri: ti.i32, n_tri: vec3):
    """Best face of A: (sep_all, sep_ok, face_ok, support_vert_ok).

    sep = min over B of (n . x) - offset; the face normal is rotated into B's
    frame once, so B's vertices are read raw. support_vert_ok is B's vertex
    (local index) realising the minimum, for the one-point fallback.
    """
    q_ab = quat_conj(q_ba)
    sep_all = NO_AXIS
    sep_ok = NO_AXIS
    face_ok = -1
    vert_ok = -1
    fs = pool.face_start[pa]
    vs = pool.vert_start[pb]
    vc = pool.vert_count[pb]
    for i in range(pool.face_count[pa]):
        n = pool.face_normal[fs + i]
        nb = quat_rotate(q_ab, n)
        lo = 3.0e38
        arg = 0
        for j in range(vc):
            d = dot(nb, pool.vert[vs + j])
            if d < lo:
                lo = d
                arg = j
        sep = dot(n, p_ba) + lo - pool.face_offset[fs + i]
        sep_all = ti.max(sep_all, sep)
        if (tri == 0 or -dot(n, n_tri) > FRONT_MIN_COS) and sep > sep_ok:
            sep_ok = sep
            face_ok = i
            vert_ok = arg
    return sep_all, sep_ok, face_ok, vert_ok


@ti.func
def face_query_b(pool: ti.template(), pa: ti.i32, pb: ti.i32, q_ba: vec4, p_ba: vec3, tri: ti.i32):
    """Best face of B: (sep_all, sep_ok, face_ok, support_vert_ok); a triangle allows face 0 only."""
    sep_all = NO_AXIS
    sep_ok = NO_AXIS
    face_ok = -1
    vert_ok = -1
    fs = pool.face_start[pb]
    vs = pool.vert_start[pa]
    vc = pool.vert_count[pa]
    for j in range(pool.face_count[pb]):
        n = quat_rotate(q_ba, pool.face_normal[fs + j])
        off = pool.face_offset[fs + j] + dot(n, p_ba)
        lo = 3.0e38
        arg = 0
        for i in range(vc):
            d = dot(n, pool.vert[vs + i])
            if d < lo:
                lo = d
                arg = i
        sep = lo - off
        sep_all = ti.max(sep_all, sep)
        if (tri == 0 or j == 0) and sep > sep_ok:
            sep_ok = sep
            face_ok = j
            vert_ok = arg
    return sep_all, sep_ok, face_ok, vert_ok


@ti.func
def _edge_axis(e1: vec3, e2: vec3):
    """Unit cross product of two edge directions, and whether it is meaningful (not parallel)."""
    c = cross(e1, e2)
    l = norm(c)
    ok = l > EDGE_PARALLEL_SIN * ti.sqrt(dot(e1, e1) * dot(e2, e2))
    return c / ti.max(l, 1.0e-30), ok


@ti.func
def edge_query_solid(pool: ti.template(), pa: ti.i32, pb: ti.i32, q_ba: vec4, p_ba: vec3):
    """Best edge pair of two solids: (sep, edge_a, edge_b, axis) with axis from A to B.

    Outer loop over B's edges so each B edge is rotated into A's frame once;
    the inner loop reads A's edges raw.
    """
    best = NO_AXIS
    best_a = -1
    best_b = -1
    best_axis = vec3(0.0, 0.0, 1.0)
    ca = pool.centroid[pa]
    es_a = pool.edge_start[pa]
    es_b = pool.edge_start[pb]
    for jb in range(pool.edge_count[pb]):
        ivb = pool.edge_vert[es_b + jb]
        ifb = pool.edge_face[es_b + jb]
        q0 = to_a(q_ba, p_ba, pool.vert[ivb[0]])
        q1 = to_a(q_ba, p_ba, pool.vert[ivb[1]])
        # arcs of the Minkowski difference A - B use B's normals negated
        c = -quat_rotate(q_ba, pool.face_normal[ifb[0]])
        d = -quat_rotate(q_ba, pool.face_normal[ifb[1]])
        d_x_c = cross(d, c)
        for ja in range(pool.edge_count[pa]):
            iva = pool.edge_vert[es_a + ja]
            ifa = pool.edge_face[es_a + ja]
            a = pool.face_normal[ifa[0]]
            b = pool.face_normal[ifa[1]]
            b_x_a = cross(b, a)
            cba = dot(c, b_x_a)
            dba = dot(d, b_x_a)
            adc = dot(a, d_x_c)
            bdc = dot(b, d_x_c)
            # Gregorius' IsMinkowskiFace: the arcs AB and CD cross on the unit sphere
            if cba * dba < 0.0 and adc * bdc < 0.0 and cba * bdc > 0.0:
                p0 = pool.vert[iva[0]]
                axis, ok = _edge_axis(pool.vert[iva[1]] - p0, q1 - q0)
                if ok:
                    if dot(axis, p0 - ca) < 0.0:
                        axis = -axis
                    sep = dot(axis, q0 - p0)
                    if sep > best:
                        best = sep
                        best_a = ja
                        best_b = jb
                        best_axis = axis
    return best, best_a, best_b, best_axis


@ti.func
def edge_query_triangle(pool: ti.template(), pa: ti.i32, pb: ti.i32, q_ba: vec4, p_ba: vec3, n_tri: vec3) -> ti.f32:
    """Best edge-pair separation of a solid A and a triangle B, for the apartness test only.

    Triangle edges never give a contact normal (see the module docstring), so
    only the largest separation is returned.
    """
    sep_all = NO_AXIS
    ct = to_a(q_ba, p_ba, pool.centroid[pb])
    es_a = pool.edge_start[pa]
    es_b = pool.edge_start[pb]
    for jb in range(pool.edge_count[pb]):
        ivb = pool.edge_vert[es_b + jb]
        q0 = to_a(q_ba, p_ba, pool.vert[ivb[0]])
        e2 = to_a(q_ba, p_ba, pool.vert[ivb[1]]) - q0
        out = cross(e2, n_tri)  # in the triangle's plane, perpendicular to the edge
        if dot(out, q0 - ct) < 0.0:
            out = -out
        for ja in range(pool.edge_count[pa]):
            iva = pool.edge_vert[es_a + ja]
            ifa = pool.edge_face[es_a + ja]
            a = pool.face_normal[ifa[0]]
            b = pool.face_normal[ifa[1]]
            # A's arc a->b crosses the great circle perpendicular to e2 ...
            if dot(a, e2) * dot(b, e2) < 0.0:
                p0 = pool.vert[iva[0]]
                axis, ok = _edge_axis(pool.vert[iva[1]] - p0, e2)
                if ok:
                    # ... at the point of the (minor) arc, which faces a + b
                    if dot(axis, a + b) < 0.0:
                        axis = -axis
                    # B's support towards A (-axis) must be this edge: -axis in its half circle
                    if -dot(axis, out) > 0.0:
                        sep_all = ti.max(sep_all, dot(axis, q0 - p0))
    return sep_all
