"""The separating-axis queries of ``sat.py`` specialised for two boxes (the 15-axis test).

Box-box is the common pair of the piles and stacks, and the generic queries pay for
generality there: 2 x 6 faces x 8 vertices of dot products and 12 x 12 edge pairs of
Gauss-map tests. For two boxes every support is a sum of |cosine| x half extent
(Gottschalk et al., "OBBTree", SIGGRAPH 1996), so the 6 face axes and the 9 edge-direction
pairs are closed forms on the 3x3 rotation between the boxes.

The outputs mean exactly what the generic queries return (same face, vertex and edge
indices of ``polytope.box_polytope``, same axis orientation), so the contact builders
(``clip.face_contact``, ``polytope._edge_contact``) and the feature ids are shared:

* face i of a box is axis ``i // 2`` with sign ``-1, +1`` for ``i % 2 = 0, 1``, offset the
  half extent; vertex index ``4 (x > 0) + 2 (y > 0) + (z > 0)``; ties between faces go to
  the lower index (strict ``>``, as in ``sat.py``), ties between support vertices to the
  lower vertex index (as the generic strict ``<`` over vertices in index order);
* of the two edge pairs of a direction pair (k of A, l of B) that span Minkowski faces,
  the generic loop keeps the larger separation, |c . p| - r_A - r_B with c = e_k x u_l
  oriented from A to B: the classic formula. A pair whose axis is a face axis of either box
  (a transverse component exactly 0) is not a Minkowski face there (Gregorius' strict
  test fails) and is skipped here too; the face axis covers it.

Separations agree with the generic ones to rounding (a few ulp), which only matters at
exact ties; the choices stay deterministic.
"""

import numpy as np
import taichi as ti

from ..math3d import cross, dot, norm, quat_to_mat
from ..polytope import box_polytope
from .tolerances import EDGE_PARALLEL_SIN, NO_AXIS

vec3 = ti.math.vec3
vec4 = ti.math.vec4

_BOX = box_polytope([1.0, 1.0, 1.0])
_BIT = (4, 2, 1)  # vertex index weight of axis x, y, z


def _edge_table() -> list[tuple[int, int, int]]:
    """(edge index, axis, low vertex) of every box edge, in the pool's edge order."""
    rows = []
    for e, (v0, v1) in enumerate(_BOX.edges.tolist()):
        axis = _BIT.index(v0 ^ v1)
        rows.append((e, axis, min(v0, v1)))
    return rows


EDGE_TABLE = _edge_table()
assert np.allclose(_BOX.face_normals, [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]])
assert all(np.allclose(v, [(1 if i & 4 else -1), (1 if i & 2 else -1), (1 if i & 1 else -1)])
           for i, v in enumerate(_BOX.vertices))


@ti.func
def _edge_index(axis: ti.i32, low: ti.i32) -> ti.i32:
    e = -1
    for t in ti.static(EDGE_TABLE):
        if axis == t[1] and low == t[2]:
            e = t[0]
    return e


@ti.func
def box_half(pool: ti.template(), poly: ti.i32) -> vec3:
    """Half extents of a box polytope: its (+, +, +) vertex."""
    return pool.vert[pool.vert_start[poly] + 7]


@ti.func
def box_face_queries(pool: ti.template(), pa: ti.i32, pb: ti.i32, q_ba: vec4, p_ba: vec3):
    """``face_query_a`` and ``face_query_b`` of two solid boxes, and the rotation and half
    extents for ``box_edge_query``: (fa_all, fa_ok, face_a, vert_a, fb_all, fb_ok, face_b,
    vert_b, R, ha, hb); R maps B-local directions to A-local (columns = B's axes)."""
    ha = box_half(pool, pa)
    hb = box_half(pool, pb)
    r = quat_to_mat(q_ba)
    ar = ti.abs(r)
    fa = NO_AXIS
    face_a = -1
    vert_a = -1
    for k in ti.static(range(3)):
        t = ar[k, 0] * hb[0] + ar[k, 1] * hb[1] + ar[k, 2] * hb[2] + ha[k]
        for si in ti.static(range(2)):
            s = ti.static(-1.0 if si == 0 else 1.0)
            sep = s * p_ba[k] - t
            if sep > fa:
                fa = sep
                face_a = 2 * k + si
                # B's vertex minimising (s R[k, :]) . v: coordinate l positive where s R[k, l] < 0
                v = 0
                for l in ti.static(range(3)):
                    if s * r[k, l] < 0.0:
                        v += _BIT[l]
                vert_a = v
    fb = NO_AXIS
    face_b = -1
    vert_b = -1
    for l in ti.static(range(3)):
        col = vec3(r[0, l], r[1, l], r[2, l])
        t = ar[0, l] * ha[0] + ar[1, l] * ha[1] + ar[2, l] * ha[2] + hb[l]
        cp = dot(col, p_ba)
        for si in ti.static(range(2)):
            s = ti.static(-1.0 if si == 0 else 1.0)
            sep = -s * cp - t
            if sep > fb:
                fb = sep
                face_b = 2 * l + si
                v = 0
                for k in ti.static(range(3)):
                    if s * r[k, l] < 0.0:
                        v += _BIT[k]
                vert_b = v
    return fa, fa, face_a, vert_a, fb, fb, face_b, vert_b, r, ha, hb


@ti.func
def box_edge_query(r: ti.template(), ha: vec3, hb: vec3, p_ba: vec3):
    """``edge_query_solid`` of two boxes: (sep, edge_a, edge_b, axis A -> B in A's frame)."""
    best = NO_AXIS
    best_a = -1
    best_b = -1
    best_axis = vec3(0.0, 0.0, 1.0)
    for l in ti.static(range(3)):  # B's edge direction (outer, as in sat.py)
        u = vec3(r[0, l], r[1, l], r[2, l])
        for k in ti.static(range(3)):  # A's edge direction
            ek = vec3(0.0)
            ek[k] = 1.0
            c = cross(ek, u)
            n = norm(c)
            if n > EDGE_PARALLEL_SIN:
                d = c / n
                if dot(d, p_ba) < 0.0:
                    d = -d
                db = vec3(dot(d, vec3(r[0, 0], r[1, 0], r[2, 0])), dot(d, vec3(r[0, 1], r[1, 1], r[2, 1])),
                          dot(d, vec3(r[0, 2], r[1, 2], r[2, 2])))  # d in B's frame
                k1 = ti.static((k + 1) % 3)
                k2 = ti.static((k + 2) % 3)
                l1 = ti.static((l + 1) % 3)
                l2 = ti.static((l + 2) % 3)
                # an axis along a face normal of either box is that face's (skipped, see module doc)
                if d[k1] != 0.0 and d[k2] != 0.0 and db[l1] != 0.0 and db[l2] != 0.0:
                    ra = ti.abs(d[k1]) * ha[k1] + ti.abs(d[k2]) * ha[k2]
                    rb = ti.abs(db[l1]) * hb[l1] + ti.abs(db[l2]) * hb[l2]
                    sep = dot(d, p_ba) - ra - rb
                    if sep > best:
                        # A's edge supporting +d, B's edge supporting -d (low ends: bit k / l clear)
                        low_a = ti.select(d[k1] > 0.0, _BIT[k1], 0) + ti.select(d[k2] > 0.0, _BIT[k2], 0)
                        low_b = ti.select(db[l1] < 0.0, _BIT[l1], 0) + ti.select(db[l2] < 0.0, _BIT[l2], 0)
                        best = sep
                        best_a = _edge_index(k, low_a)
                        best_b = _edge_index(l, low_b)
                        best_axis = d
    return best, best_a, best_b, best_axis
