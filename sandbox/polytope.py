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
    v = np.asarray([a, b, c], dtype=np.float64)
    n = np.cross(v[1] - v[0], v[2] - v[0])
    area2 = np.linalg.norm(n)
    if not np.isfinite(area2) or area2 <= 1e-12 * max(1.0, float(np.ptp(v, axis=0).max()) ** 2):
        raise GeometryError("degenerate triangle (zero area)")
    n /= area2
    loops = [np.array([0, 1, 2]), np.array([0, 2, 1])]
    normals = np.array([n, -n])
    offsets = np.array([v[0] @ n, -(v[0] @ n)])
    edges = np.array([[0, 1], [1, 2], [0, 2]])
    edge_faces = np.array([[0, 1], [0, 1], [0, 1]])
    return Polytope(v, normals, offsets, loops, edges, edge_faces)


