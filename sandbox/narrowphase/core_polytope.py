"""Spheres and capsules against polytopes (box, hull, one-sided mesh triangle).

The rounded shape is a core (a point for a sphere, a segment for a capsule)
inflated by its radius, so the pair reduces to the exact signed distance
between the core and the polytope, minus the radius. For a unit direction u
(pointing from the polytope to the core) the gap

    g(u) = min over core of u.x  -  max over polytope of u.x

is a lower bound of the signed distance, and the signed distance is the
maximum of g over all directions. That maximum is reached at one of a finite
set of candidates, so the maximum over the candidates is exact:

* the polytope's face normals (closest features: face and core point, or any
  penetration resolved through a face);
* cross(core segment, edge) for every edge whose Gauss-map arc contains it
  (edge interior against segment interior; also every penetration through
  a face of the Minkowski sum that is not a polytope face);
* for separated shapes, the direction from each polytope vertex, and from each
  edge's closest point, to the closest point of the core.

Face and edge-arc candidates cost one dot product (the support is known);
vertex and edge-closest ones a support scan over the vertices, O(V^2 + E V),
about 16k dot products for a 64-vertex hull.

A capsule whose best axis is a face normal is clipped against that face's side
planes, and both ends of the clipped segment within the margin become points,
so a capsule lying on a face gets two points (it would rock on one).

One-sided mesh triangles: the core is clipped to the triangle's prism and
pushed along the front normal only, by the plane distance; there is no
contact once the core's centre is behind the plane, nor where the core is not
over the triangle. Edges and vertices of a triangle never give the normal:
without mesh adjacency a seam between coplanar triangles cannot be told from
a boundary edge, and a sphere rolling over a seam would be kicked by the
edge normal ("ghost collisions"; see ``polytope.py``). The price is at
genuine boundary edges, where a core rolling off the mesh loses its contact
once its centre leaves the triangle instead of rolling round the edge.

Feature ids: one point gets ``type << 8 | index`` (type 0 face, 1 edge arc,
2 vertex, 3 edge closest point; index local to the polytope); points from
clipping the core to a face (capsule on a face, anything on a triangle) get
``1024 | end << 8 | face`` (end 0 or 1 of the clipped segment).
"""

import taichi as ti

from ..math3d import cross, dot, norm, quat_rotate, quat_rotate_inv
from ..shapes import CAPSULE, TRIANGLE
from .manifold import Manifold, ShapePose, manifold_add
from .segments import closest_on_segment, closest_segments
from .tolerances import CLIP_EPS, EDGE_PARALLEL_SIN, FACE_PREFERENCE_ABS, LENGTH_EPS, LENGTH_EPS2, NO_AXIS

vec3 = ti.math.vec3

FACE, EDGE_ARC, VERTEX, EDGE_CLOSEST = 0, 1, 2, 3
FLAT_BIT = 1024


@ti.func
def _support(pool: ti.template(), poly: ti.i32, u: vec3) -> ti.f32:
    """max over the polytope's vertices of u.x (local frame)."""
    hi = -3.0e38
    vs = pool.vert_start[poly]
    for j in range(pool.vert_count[poly]):
        hi = ti.max(hi, dot(u, pool.vert[vs + j]))
    return hi


@ti.func
def _in_arc(u: vec3, a: vec3, b: vec3) -> ti.i32:
    """u (perpendicular to the edge) lies on the minor arc from face normal a to face normal b."""
    w = cross(a, b)
    return dot(cross(a, u), w) >= 0.0 and dot(cross(u, b), w) >= 0.0


@ti.func
def collide_core_polytope(pool: ti.template(), a: ShapePose, b: ShapePose, margin: ti.f32) -> Manifold:
    """Sphere or capsule ``a`` against polytope ``b``; the normal points from a to b."""
    m = Manifold(count=0, normal=vec3(0.0, 0.0, -1.0))
    poly = b.poly
    r = a.radius
    # core in b's frame
    c = quat_rotate_inv(b.rot, a.pos - b.pos)
    hh = a.half_height if a.kind == CAPSULE else 0.0
    h = quat_rotate_inv(b.rot, quat_rotate(a.rot, vec3(0.0, 0.0, hh)))
    c0 = c - h
    c1 = c + h
    dseg = c1 - c0
    is_segment = dot(dseg, dseg) > LENGTH_EPS2
    fs = pool.face_start[poly]
    es = pool.edge_start[poly]
    vs = pool.vert_start[poly]

    u = vec3(0.0, 0.0, 1.0)  # contact axis, from the polytope to the core (b's frame)
    clip_face = -1  # face whose prism clips the core into (up to) two points
    single = 0  # make one point from the best candidate if clipping gave none
    g_face, i_face, cp_face = NO_AXIS, -1, c0
    g_other, id_other, u_other, cp_other = NO_AXIS, 0, vec3(0.0, 0.0, 1.0), c0
    if b.kind == TRIANGLE:
        # one-sided: the front normal, over the triangle only, and nothing once the centre is behind
        if dot(pool.face_normal[fs], c) - pool.face_offset[fs] >= 0.0:
            u = pool.face_normal[fs]
            clip_face = 0
    else:
        for i in range(pool.face_count[poly]):
            n = pool.face_normal[fs + i]
            cp = c0
            if dot(n, c1) < dot(n, c0):
                cp = c1
            g = dot(n, cp) - pool.face_offset[fs + i]
            if g > g_face:
                g_face, i_face, cp_face = g, i, cp

        for e in range(pool.edge_count[poly]):
            iv = pool.edge_vert[es + e]
            p0 = pool.vert[iv[0]]
            p1 = pool.vert[iv[1]]
            edge = p1 - p0
            cs, ce = closest_segments(c0, c1, p0, p1)
            if is_segment:
                w = cross(dseg, edge)
                l = norm(w)
                if l > EDGE_PARALLEL_SIN * ti.sqrt(dot(dseg, dseg) * dot(edge, edge)):
                    w /= l
                    ifc = pool.edge_face[es + e]
                    na = pool.face_normal[ifc[0]]
                    nb = pool.face_normal[ifc[1]]
                    if not _in_arc(w, na, nb):
                        w = -w
                    if _in_arc(w, na, nb):
                        g = dot(w, c0) - dot(w, p0)  # w is perpendicular to the segment
                        if g > g_other:
                            g_other, id_other, u_other, cp_other = g, (EDGE_ARC << 8) | e, w, cs
            # direction from the edge's closest point to the core
            w = cs - ce
            l = norm(w)
            if l > LENGTH_EPS:
                w /= l
                g = ti.min(dot(w, c0), dot(w, c1)) - _support(pool, poly, w)
                if g > g_other:
                    g_other, id_other, u_other, cp_other = g, (EDGE_CLOSEST << 8) | e, w, cs

        for j in range(pool.vert_count[poly]):
            v = pool.vert[vs + j]
            cs = closest_on_segment(v, c0, c1)
            w = cs - v
            l = norm(w)
            if l > LENGTH_EPS:
                w /= l
                g = ti.min(dot(w, c0), dot(w, c1)) - _support(pool, poly, w)
                if g > g_other:
                    g_other, id_other, u_other, cp_other = g, (VERTEX << 8) | j, w, cs

        if ti.max(g_face, g_other) - r < margin:
            single = 1
            u = u_other
            if g_other <= g_face + FACE_PREFERENCE_ABS:  # faces first: flat capsules keep two points
                u = pool.face_normal[fs + i_face]
                if is_segment:
                    clip_face = i_face
    m.normal = -quat_rotate(b.rot, u)
    m.normal_on_b = 1  # a face normal of the polytope, or the closest-point direction in its frame

    if clip_face >= 0:
        # clip the core to the face's prism: t in [lo, hi]; CLIP_EPS of slack as in clip.py
        f = fs + clip_face
        lo, hi = 0.0, 1.0
        ls = pool.face_loop_start[f]
        lc = pool.face_loop_count[f]
        for k in range(lc):
            v0 = pool.vert[pool.loop[ls + k]]
            v1 = pool.vert[pool.loop[ls + (k + 1) % lc]]
            s = cross(v1 - v0, u)  # out of the face (loops are counter-clockwise from outside)
            s /= ti.max(norm(s), 1.0e-30)
            d0 = dot(s, c0 - v0)
            d1 = dot(s, c1 - v0)
            # classify with the slack, cut at the plane itself
            if d0 > CLIP_EPS and d1 > CLIP_EPS:
                lo, hi = 1.0, 0.0
            elif d0 > CLIP_EPS:
                lo = ti.max(lo, ti.min(1.0, d0 / (d0 - d1)))
            elif d1 > CLIP_EPS:
                hi = ti.min(hi, ti.max(0.0, d0 / (d0 - d1)))
        if hi >= lo:
            off = pool.face_offset[f]
            for end in ti.static(range(2)):
                t = lo
                if ti.static(end == 1):
                    t = hi
                x = c0 + t * dseg
                sep = dot(u, x) - off - r
                # a point core, or a clip down to one point, gives one point
                if sep < margin and (ti.static(end == 0) or (hi - lo) * norm(dseg) > LENGTH_EPS):
                    manifold_add(m, b.pos + quat_rotate(b.rot, x - u * (r + 0.5 * sep)), sep,
                                 FLAT_BIT | (end << 8) | clip_face)
    if single and m.count == 0:
        g, cp, feature = g_other, cp_other, id_other
        if g_other <= g_face + FACE_PREFERENCE_ABS:
            g, cp, feature = g_face, cp_face, (FACE << 8) | i_face
        sep = g - r
        if sep < margin:
            manifold_add(m, b.pos + quat_rotate(b.rot, cp - u * (r + 0.5 * sep)), sep, feature)
    return m
