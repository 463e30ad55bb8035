"""Convex hulls for scene loading: validation, and reduction of big meshes to a small hull.

Why this is not simply ``sandbox.shapes.hull_polytope``: ``shapes`` is a Taichi
module (layer L2) and the scene layer (L1) must load without Taichi. So the
checks of ``hull_polytope`` are repeated here in numpy/scipy, with the same
thresholds (at least 4 points, finite, non-zero volume, at most
``MAX_HULL_VERTICES`` hull vertices, merged coplanar faces with Euler
characteristic 2); a test builds every hull the loader accepts with
``hull_polytope`` as well, so the two cannot drift apart silently.

Reduction (mesh files only): a mesh whose convex hull has more than
``MAX_HULL_VERTICES`` vertices is simplified by farthest-point sampling over its
hull vertices (start at the vertex farthest from the centroid, then repeatedly
add the hull vertex farthest from those chosen). Every chosen point is an
extreme point of the original hull, so the result is a convex polytope
inscribed in it that keeps its overall extent; the volume shrinks a little
(an icosphere of 642 vertices keeps about 94 % of its volume at 64 vertices).
"""

from __future__ import annotations

import numpy as np

MAX_HULL_VERTICES = 64
"""Largest hull accepted; equal to ``sandbox.shapes.MAX_POLY_VERTS`` (checked by a test)."""

COPLANAR_TOL = 1e-6
"""[1] Same coplanarity tolerance as ``hull_polytope`` (cosine distance of face normals)."""


class HullError(ValueError):
    """A point set does not make an acceptable hull; the loader re-raises it as a SceneError."""


def _qhull(pts: np.ndarray):
    from scipy.spatial import ConvexHull, QhullError

    try:
        return ConvexHull(pts)
    except (QhullError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise HullError(f"hull is degenerate (flat or collinear points): {first}") from None


def _check_points(points) -> np.ndarray:
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise HullError("hull vertices must be a list of [x, y, z] numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
        raise HullError(f"a hull needs at least 4 points of 3 coordinates, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise HullError("hull vertices contain NaN or inf")
    if float(np.ptp(pts, axis=0).max()) <= 0:
        raise HullError("hull is degenerate (all points coincide)")
    return pts


def _check_hull(pts: np.ndarray, hull) -> None:
    """Volume and merged-face topology checks, exactly as ``hull_polytope`` does them."""
    scale = np.float64(np.ptp(pts, axis=0).max())  # numpy: scale**3 may overflow to inf, never raise
    if not hull.volume > 1e-9 * scale**3:
        raise HullError("hull is degenerate (zero volume)")
    groups: list[tuple[np.ndarray, float, set]] = []
    for tri, eq in zip(hull.simplices, hull.equations):
        n, d = eq[:3], -eq[3]
        for gn, gd, members in groups:
            if np.dot(gn, n) > 1 - COPLANAR_TOL and abs(gd - d) < COPLANAR_TOL * scale * 10:
                members.update(int(v) for v in tri)
                break
        else:
            groups.append((n, d, {int(v) for v in tri}))
    edges = set()
    for n, _, members in groups:
        idx = np.fromiter(members, dtype=np.int64)
        p = pts[idx]
        c = p.mean(axis=0)
        u = p[0] - c
        un = np.linalg.norm(u)
        if un <= 0:
            raise HullError("hull topology is inconsistent (a face collapses to a point)")
        u /= un
        w = np.cross(n, u)
        loop = idx[np.argsort(np.arctan2((p - c) @ w, (p - c) @ u))]
        for i in range(len(loop)):
            a, b = int(loop[i]), int(loop[(i + 1) % len(loop)])
            edges.add((min(a, b), max(a, b)))
    n_verts = len(np.unique(hull.simplices))
    if n_verts - len(edges) + len(groups) != 2:
        raise HullError("hull topology is inconsistent (Euler characteristic != 2); points may be nearly coplanar")


def hull_vertices(points, *, max_vertices: int = MAX_HULL_VERTICES) -> np.ndarray:
    """The vertices of the convex hull of ``points`` (interior points dropped), validated.

    Raises HullError when the hull is degenerate or has more than ``max_vertices`` vertices.
    """
    pts = _check_points(points)
    hull = _qhull(pts)
    used = np.unique(hull.simplices)
    if len(used) > max_vertices:
        raise HullError(
            f"hull has {len(used)} vertices; at most {max_vertices} are supported "
            "(give fewer points, or a mesh file via 'path', which is simplified automatically)"
        )
    _check_hull(pts, hull)
    return pts[used].copy()


def farthest_point_subset(points: np.ndarray, count: int) -> np.ndarray:
    """Indices of ``count`` points chosen by farthest-point sampling (deterministic)."""
    pts = np.asarray(points, dtype=np.float64)
    if count >= len(pts):
        return np.arange(len(pts))
    first = int(np.argmax(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))
    chosen = [first]
    dist = np.linalg.norm(pts - pts[first], axis=1)
    for _ in range(count - 1):
        nxt = int(np.argmax(dist))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(pts - pts[nxt], axis=1))
    return np.asarray(sorted(chosen), dtype=np.int64)


def reduce_to_hull(points, *, max_vertices: int = MAX_HULL_VERTICES) -> tuple[np.ndarray, int]:
    """Hull of a (mesh) point set, simplified to at most ``max_vertices`` vertices.

    Returns (hull vertices, number of hull vertices before simplification).
    """
    pts = _check_points(points)
    hull = _qhull(pts)
    verts = pts[np.unique(hull.simplices)]
    original = len(verts)
    if original > max_vertices:
        verts = verts[farthest_point_subset(verts, max_vertices)]
    return hull_vertices(verts, max_vertices=max_vertices), original
