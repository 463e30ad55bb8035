"""Convex polytopes on the host: boxes, hulls (coplanar faces merged) and triangles.

Plain numpy/scipy, no Taichi, so the scene layer validates hulls with exactly
the code the engine uploads (``shapes.PolytopePool``). Faces are merged coplanar
polygons, not triangles, so a box face is one quad and face-face manifolds come
out as 4 stable points. A triangle is a polytope with two faces (front, back)
and three edges; the narrowphase treats it one-sided.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PLANE, SPHERE, CAPSULE, BOX, HULL, TRIANGLE = 0, 1, 2, 3, 4, 5
KIND_NAMES = {PLANE: "plane", SPHERE: "sphere", CAPSULE: "capsule", BOX: "box", HULL: "hull", TRIANGLE: "triangle"}
POLYTOPE_KINDS = (BOX, HULL, TRIANGLE)
MAX_POLY_VERTS = 64
"""Largest hull the narrowphase accepts (it keeps one hull in registers/local memory)."""


class GeometryError(ValueError):
    """Raised by the builders below; the scene loader re-raises it as a SceneError with its entry."""


@dataclass
class Polytope:
    """A convex polytope in its local frame (float64, built on the host once)."""

    vertices: np.ndarray  # (V, 3)
    face_normals: np.ndarray  # (F, 3) outward unit normals
    face_offsets: np.ndarray  # (F,) plane: n . x = offset
    face_loops: list  # F arrays of vertex indices, counter-clockwise seen from outside
    edges: np.ndarray  # (E, 2) vertex indices
    edge_faces: np.ndarray  # (E, 2) the two faces sharing the edge

    @property
    def centroid(self) -> np.ndarray:
        return self.vertices.mean(axis=0)


def _edges_from_loops(loops) -> tuple[np.ndarray, np.ndarray]:
    owner: dict[tuple[int, int], list[int]] = {}
    for f, loop in enumerate(loops):
        for i in range(len(loop)):
            a, b = int(loop[i]), int(loop[(i + 1) % len(loop)])
            owner.setdefault((min(a, b), max(a, b)), []).append(f)
    edges, faces = [], []
    for key in sorted(owner):
        fs = owner[key]
        if len(fs) != 2:
            raise GeometryError("polytope is not closed (an edge does not have exactly two faces)")
        edges.append(key)
        faces.append(fs)
    return np.asarray(edges, dtype=np.int64), np.asarray(faces, dtype=np.int64)


def box_polytope(half_extents) -> Polytope:
    h = np.asarray(half_extents, dtype=np.float64)
    if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise GeometryError(f"box half_extents must be three finite numbers > 0, got {half_extents!r}")
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    verts = signs * h
    # vertex index = 4*(x>0) + 2*(y>0) + (z>0); loops counter-clockwise from outside
    loops = [
        np.array([0, 1, 3, 2]),  # -x
        np.array([4, 6, 7, 5]),  # +x
        np.array([0, 4, 5, 1]),  # -y
        np.array([2, 3, 7, 6]),  # +y
        np.array([0, 2, 6, 4]),  # -z
        np.array([1, 5, 7, 3]),  # +z
    ]
    normals = np.array([[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=np.float64)
    offsets = np.array([h[0], h[0], h[1], h[1], h[2], h[2]])
    edges, edge_faces = _edges_from_loops(loops)
    return Polytope(verts, normals, offsets, loops, edges, edge_faces)


def hull_polytope(points, *, coplanar_tol: float = 1e-6) -> Polytope:
    """Convex hull of ``points`` with coplanar triangles merged into polygon faces."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
        raise GeometryError(f"a hull needs at least 4 points of 3 coordinates, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise GeometryError("hull vertices contain NaN or inf")
    scale = float(np.ptp(pts, axis=0).max())
    if scale <= 0:
        raise GeometryError("hull is degenerate (all points coincide)")
    try:
        hull = ConvexHull(pts)
    except QhullError as exc:
        raise GeometryError(f"hull is degenerate (flat or collinear points): {str(exc).splitlines()[0]}") from None
    if hull.volume <= 1e-9 * scale**3:
        raise GeometryError("hull is degenerate (zero volume)")
    used = np.unique(hull.simplices)
    if len(used) > MAX_POLY_VERTS:
        raise GeometryError(
            f"hull has {len(used)} vertices; at most {MAX_POLY_VERTS} are supported (simplify or decimate the mesh)"
        )
    remap = -np.ones(len(pts), dtype=np.int64)
    remap[used] = np.arange(len(used))
    verts = pts[used]
    # group hull triangles by plane
    groups: list[tuple[np.ndarray, float, list[int]]] = []
    for tri, eq in zip(hull.simplices, hull.equations):
        n, d = eq[:3], -eq[3]
        for gn, gd, members in groups:
            if np.dot(gn, n) > 1 - coplanar_tol and abs(gd - d) < coplanar_tol * scale * 10:
                members.extend(int(v) for v in tri)
                break
        else:
            groups.append((n, d, [int(v) for v in tri]))
    normals, offsets, loops = [], [], []
    for n, _, members in groups:
        idx = np.unique(remap[np.asarray(members)])
        p = verts[idx]
        c = p.mean(axis=0)
        u = p[0] - c
        u /= np.linalg.norm(u)
        w = np.cross(n, u)
        ang = np.arctan2((p - c) @ w, (p - c) @ u)
        loop = idx[np.argsort(ang)]
        normals.append(n / np.linalg.norm(n))
        offsets.append(float(np.mean(verts[loop] @ normals[-1])))
        loops.append(loop)
    edges, edge_faces = _edges_from_loops(loops)
    if len(verts) - len(edges) + len(loops) != 2:
        raise GeometryError("hull topology is inconsistent (Euler characteristic != 2); points may be nearly coplanar")
    return Polytope(verts, np.asarray(normals), np.asarray(offsets), loops, edges, edge_faces)


def triangle_polytope(a, b, c) -> Polytope:
    """The two-sided triangle with corners a, b, c (``triangle_polytopes`` of one)."""
    return triangle_polytopes(np.asarray([[a, b, c]], dtype=np.float64))[0]


def triangle_polytopes(corners: np.ndarray) -> list[Polytope]:
    """A two-sided triangle (faces n and -n) for each (3, 3) corner triple of ``corners``
    (N, 3, 3), in array passes: a terrain's 18 000 triangles took ~1 s one at a time. The dot
    products go through matmul, the product one-at-a-time ``@`` and ``norm`` used: the same
    numbers (checked on the shipped terrains)."""
    v = np.asarray(corners, dtype=np.float64)
    if len(v) == 0:
        return []
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    area2 = np.sqrt((n[:, None, :] @ n[:, :, None])[:, 0, 0])
    scale = np.maximum(1.0, np.ptp(v, axis=1).max(axis=1) ** 2)
    if np.any(~np.isfinite(area2) | (area2 <= 1e-12 * scale)):
        raise GeometryError("degenerate triangle (zero area)")
    n /= area2[:, None]
    offsets = (v[:, 0][:, None, :] @ n[:, :, None])[:, 0, 0]
    loops = [np.array([0, 1, 2]), np.array([0, 2, 1])]
    edges = np.array([[0, 1], [1, 2], [0, 2]])
    edge_faces = np.array([[0, 1], [0, 1], [0, 1]])
    return [Polytope(v[i], np.array([n[i], -n[i]]), np.array([offsets[i], -offsets[i]]), loops, edges, edge_faces)
            for i in range(len(v))]



# ---------------------------------------------------------------------------- clipping and overlap
def clip_convex(points, normal, offset: float) -> np.ndarray | None:
    """Vertices of conv(points) cut by the plane n . x = offset, keeping n . x <= offset.

    Returns None when nothing of positive volume is left. The cut points are the
    intersections of the hull's edges (triangulated, so face diagonals too) with the
    plane; the ones that land inside a face are not extreme and drop out of the next
    hull. Two cells cut by the same plane with opposite normals share that face
    exactly, so a partition made this way conserves volume to rounding.
    """
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    try:
        hull = ConvexHull(pts)
    except (QhullError, ValueError):
        return None
    pts = pts[hull.vertices]
    remap = -np.ones(hull.points.shape[0], dtype=np.int64)
    remap[hull.vertices] = np.arange(len(hull.vertices))
    d = pts @ n - float(offset)
    scale = float(np.ptp(pts, axis=0).max())
    on = np.abs(d) <= 1e-12 * max(scale, 1e-300)
    d = np.where(on, 0.0, d)
    if np.all(d <= 0):
        return pts
    if np.all(d >= 0):
        return None
    tri = remap[hull.simplices]
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1), axis=0)
    da, db = d[edges[:, 0]], d[edges[:, 1]]
    cross = (da < 0) & (db > 0) | (da > 0) & (db < 0)
    a, b = pts[edges[cross, 0]], pts[edges[cross, 1]]
    t = (da[cross] / (da[cross] - db[cross]))[:, None]
    out = np.vstack([pts[d <= 0], a + t * (b - a)])
    try:
        kept = ConvexHull(out)
    except (QhullError, ValueError):
        return None
    if kept.volume <= 1e-12 * scale**3:
        return None
    return out[kept.vertices]


def _axes(points) -> tuple[np.ndarray, np.ndarray]:
    """Outward face normals and unit edge directions of conv(points) (triangulated hull)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(np.asarray(points, dtype=np.float64))
    tri = hull.simplices
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1), axis=0)
    e = hull.points[edges[:, 1]] - hull.points[edges[:, 0]]
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    normals = np.unique(np.round(hull.equations[:, :3], 12), axis=0)
    return normals, np.unique(np.round(e * np.sign(e[:, :1] + 1e-300), 12), axis=0)


def penetration_depth(a, b) -> tuple[float, np.ndarray]:
    """Overlap of conv(a) and conv(b) along the best separating-axis candidate.

    Returns (depth [m], axis): depth > 0 is the minimum translation distance that
    separates the two hulls (the separating-axis theorem: for convex polytopes the
    minimum over face normals of both and cross products of edge pairs is exact),
    depth <= 0 means they are separated (or touching) along ``axis``, which then
    points from a to b. Face normals are tried first, so separated or touching
    pairs never pay for the edge-edge axes.
    """
    pa, pb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)

    def best(axes):
        ha, hb = pa @ axes.T, pb @ axes.T
        over_ab = ha.max(axis=0) - hb.min(axis=0)  # a on the low side
        over_ba = hb.max(axis=0) - ha.min(axis=0)
        over = np.minimum(over_ab, over_ba)
        k = int(np.argmin(over))
        sign = 1.0 if over_ab[k] <= over_ba[k] else -1.0
        return float(over[k]), sign * axes[k]

    na, ea = _axes(pa)
    nb, eb = _axes(pb)
    depth, axis = best(np.vstack([na, nb]))
    if depth <= 0:
        return depth, axis
    cross = np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3)
    length = np.linalg.norm(cross, axis=1)
    cross = cross[length > 1e-9] / length[length > 1e-9, None]
    if len(cross):
        d2, axis2 = best(cross)
        if d2 < depth:
            return d2, axis2
    return depth, axis
