"""Polytope pairs (box, hull, mesh triangle) and polytopes against planes.

Polytope-polytope is SAT + clipping (Gregorius, GDC 2013; the same scheme as
Box2D's 3D prototype and Bullet's ``btPolyhedralContactClipping``): the axis of
largest separation decides between a face contact (clip, up to four points,
see ``clip.py``) and an edge-edge contact (one point at the closest points of
the two edges). Near ties are broken towards faces, and towards A's face over
B's (``SAT_*_TOL``): a resting pair then keeps its reference face and its
feature ids from frame to frame instead of flickering between equivalent
features.

Edge-edge feature id: ``2 << 28 | edge_a << 8 | edge_b`` (local edge indices,
at most 186 for a 64-vertex hull, 8 bits each).

One-sided mesh triangles (always B). ``sat.py`` reports the largest
separation over all axes and over the axes allowed to push A towards the
triangle's front: the triangle's front face and A's faces whose push has a
positive cosine with the front normal; triangle edges are never allowed (see
``sat.py``: a seam cannot be told from a boundary without adjacency, and
flat meshes are made of seams). The rule, in order:

1. if A's centroid is behind the triangle's plane, there is no contact: A has
   passed through (or comes from behind) and the front face must not pull it
   back through the mesh;
2. if the largest separation over all axes (edges included) exceeds the
   margin, no contact;
3. otherwise the contact is built from the best allowed (face) axis and
   clipped, so every point lies over the triangle (reference = triangle) or
   on it (reference = A's face), with its own honest separation; the support
   vertex fallback of ``clip.py`` is used only if it lies in the reference
   face's prism. A box beside a floor triangle, lower than it but apart
   sideways, thus gets no points (nothing of it is over the triangle) rather
   than a lift, and a box resting on a floor made of triangles always gets the
   front normal, also where it crosses a seam and an edge or sideways axis
   would separate less (the "internal edge" push of two-sided SAT). The
   price, at genuine boundary edges of a mesh, is that an edge-edge contact
   is approximated by a face contact.

Plane-polytope feature id: the polytope's local vertex index.
"""

import taichi as ti

from ..math3d import dot, quat_rotate, quat_rotate_inv
from ..shapes import BOX, HULL, TRIANGLE
from .box_sat import box_edge_query, box_face_queries
from .clip import face_contact
from .manifold import Manifold, ShapePose, manifold_add, relative_pose
from .reduce import REDUCE_PASSES, reducer_finish, reducer_needs_pass, reducer_new, reducer_visit
from .sat import edge_query_solid, edge_query_triangle, face_query_a, face_query_b, to_a
from .segments import closest_segments
from .tolerances import NO_AXIS, NO_AXIS_HALF, SAT_ABS_TOL, SAT_EDGE_REL_TOL, SAT_FACE_B_REL_TOL

vec3 = ti.math.vec3
vec4 = ti.math.vec4

EDGE_KIND = 2


@ti.func
def collide_plane_polytope(pool: ti.template(), a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    """Every vertex of b within the margin of plane a, reduced to four (in b's frame)."""
    n = a.normal
    m = Manifold(count=0, normal=n)
    n_local = quat_rotate_inv(b.rot, n)
    d_local = dot(n, a.pos - b.pos)
    vs = pool.vert_start[b.poly]
    r = reducer_new()
    for pass_index in range(REDUCE_PASSES):
        if reducer_needs_pass(r, pass_index):
            for j in range(pool.vert_count[b.poly]):
                v = pool.vert[vs + j]
                sep = dot(n_local, v) - d_local
                if sep < margin:
                    reducer_visit(r, pass_index, v - n_local * (0.5 * sep), sep, j, n_local)
    reducer_finish(r, m, b.rot, b.pos)
    return m


@ti.func
def _edge_contact(pool: ti.template(), m: ti.template(), a: ShapePose, pb: ti.i32, q_ba: vec4, p_ba: vec3,
                  edge_a: ti.i32, edge_b: ti.i32, axis: vec3, sep: ti.f32):
    """One point midway between the closest points of the two edges."""
    iva = pool.edge_vert[pool.edge_start[a.poly] + edge_a]
    ivb = pool.edge_vert[pool.edge_start[pb] + edge_b]
    ca, cb = closest_segments(pool.vert[iva[0]], pool.vert[iva[1]],
                              to_a(q_ba, p_ba, pool.vert[ivb[0]]), to_a(q_ba, p_ba, pool.vert[ivb[1]]))
    m.normal = quat_rotate(a.rot, axis)
    manifold_add(m, a.pos + quat_rotate(a.rot, 0.5 * (ca + cb)), sep, (EDGE_KIND << 28) | (edge_a << 8) | edge_b)


@ti.func
def collide_polytope_polytope(pool: ti.template(), a: ShapePose, b: ShapePose, margin: ti.f32,
                              kinds: ti.template()) -> Manifold:
    """SAT + clipping between two polytopes; b may be a one-sided mesh triangle. ``kinds``: the
    shape kinds the world has (narrowphase.collide_kinds): the queries of a kind pair it cannot
    meet are not compiled (a world of boxes compiles neither the general SAT nor the triangle's
    tests), the same branches taken for the pairs it does meet."""
    m = Manifold(count=0, normal=vec3(0.0, 0.0, 1.0))
    pa = a.poly
    pb = b.poly
    p_ba, q_ba = relative_pose(a, b)
    tri = 0
    n_tri = vec3(0.0, 0.0, 1.0)
    in_front = 1
    if ti.static(TRIANGLE in kinds):
        tri = 1 if b.kind == TRIANGLE else 0
        if tri:
            f0 = pool.face_start[pb]
            n_tri = quat_rotate(q_ba, pool.face_normal[f0])
            if dot(n_tri, pool.centroid[pa]) - (pool.face_offset[f0] + dot(n_tri, p_ba)) < 0.0:
                in_front = 0
    boxes = a.kind == BOX and b.kind == BOX
    general = ti.static(HULL in kinds or TRIANGLE in kinds)  # a pair of two boxes is not the only one
    if in_front:
        fa_all, fa_ok, face_a, vert_a = NO_AXIS, NO_AXIS, -1, -1
        fb_all, fb_ok, face_b, vert_b = NO_AXIS, NO_AXIS, -1, -1
        r_ba, ha, hb = ti.math.mat3(0.0), vec3(0.0), vec3(0.0)
        if ti.static(BOX in kinds):
            if boxes:  # closed forms of the same queries (box_sat.py)
                fa_all, fa_ok, face_a, vert_a, fb_all, fb_ok, face_b, vert_b, r_ba, ha, hb = box_face_queries(
                    pool, pa, pb, q_ba, p_ba)
        if ti.static(general):
            if not boxes:
                fa_all, fa_ok, face_a, vert_a = face_query_a(pool, pa, pb, q_ba, p_ba, tri, n_tri)
                fb_all, fb_ok, face_b, vert_b = face_query_b(pool, pa, pb, q_ba, p_ba, tri)
        best_all = ti.max(fa_all, fb_all)
        e_ok, edge_a, edge_b, axis = NO_AXIS, -1, -1, vec3(0.0, 0.0, 1.0)
        if best_all < margin:  # a face already separates them: skip the costly edge pairs
            if ti.static(BOX in kinds):
                if boxes:
                    e_s, ea_s, eb_s, ax_s = box_edge_query(r_ba, ha, hb, p_ba)
                    best_all = ti.max(best_all, e_s)
                    e_ok, edge_a, edge_b, axis = e_s, ea_s, eb_s, ax_s
            if ti.static(TRIANGLE in kinds):
                if not boxes and tri:  # edges of a triangle only prove apartness, never give the normal
                    best_all = ti.max(best_all, edge_query_triangle(pool, pa, pb, q_ba, p_ba, n_tri))
            if ti.static(HULL in kinds):
                if not boxes and not tri:
                    e_s, ea_s, eb_s, ax_s = edge_query_solid(pool, pa, pb, q_ba, p_ba)
                    best_all = ti.max(best_all, e_s)
                    e_ok, edge_a, edge_b, axis = e_s, ea_s, eb_s, ax_s
        best_ok = ti.max(fa_ok, ti.max(fb_ok, e_ok))
        if best_all < margin and best_ok > NO_AXIS_HALF:
            # one call site per contact builder: every inlined copy adds to the kernel's compile time
            face_best = ti.max(fa_ok, fb_ok)
            if e_ok > face_best + SAT_EDGE_REL_TOL * ti.abs(face_best) + SAT_ABS_TOL:
                _edge_contact(pool, m, a, pb, q_ba, p_ba, edge_a, edge_b, axis, e_ok)
            else:
                ref_on_b, ref_face, support_vert = 0, face_a, vert_a
                if fb_ok > fa_ok + SAT_FACE_B_REL_TOL * ti.abs(fa_ok) + SAT_ABS_TOL:
                    ref_on_b, ref_face, support_vert = 1, face_b, vert_b
                face_contact(pool, m, a, b, q_ba, p_ba, ref_on_b, ref_face, support_vert, margin)
        elif best_all >= margin:
            m.gap = best_all  # a separating axis: the shapes are at least this far apart
    return m
