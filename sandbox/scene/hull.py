"""Convex hulls for scene loading: validation, and reduction of big meshes to a small hull.

Validation is ``sandbox.polytope.hull_polytope`` itself (numpy/scipy only), so
the loader accepts exactly the hulls the engine can upload.

Cleaning (CoACD hulls, fracture cells): ``usable_hull`` returns vertices the engine's
polytope builder accepts. Decimated or clipped hulls can have adjacent facets that
are coplanar to within 1e-6 without being coplanar, which the builder's face
merging cannot turn into a consistent polygon mesh ("polytope is not closed").
Qhull's facet merging (``C-n``, centrum radius n) at growing radii (1e-6 to 1e-3
of the hull's extent) drops the vertices that make such near-flat creases; if that
is not enough, vertices are removed one at a time, each time the one whose
removal loses the least volume. Both only ever remove vertices, so the result is
inscribed in the input hull (a bowl's 12 CoACD hulls lost at most 0.02 % volume).

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

from ..polytope import MAX_POLY_VERTS, GeometryError, hull_polytope

MAX_HULL_VERTICES = MAX_POLY_VERTS
"""Largest hull accepted: what the narrowphase supports."""

class HullError(ValueError):
    """A point set does not make an acceptable hull; the loader re-raises it as a SceneError."""


def _check_points(points) -> np.ndarray:
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise HullError("hull vertices must be a list of [x, y, z] numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 4:
        raise HullError(f"a hull needs at least 4 points of 3 coordinates, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise HullError("hull vertices contain NaN or inf")
    return pts


def hull_vertices(points, *, max_vertices: int = MAX_HULL_VERTICES) -> np.ndarray:
    """The vertices of the convex hull of ``points`` (interior points dropped), validated.

    Raises HullError when the hull is degenerate or has more than ``max_vertices`` vertices.
    """
    pts = _check_points(points)
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            poly = hull_polytope(pts)
    except GeometryError as exc:
        text = str(exc)
        if "supported" in text:
            text += " (give fewer points, or a mesh file via 'path', which is simplified automatically)"
        raise HullError(text) from None
    if len(poly.vertices) > max_vertices:
        raise HullError(f"hull has {len(poly.vertices)} vertices; at most {max_vertices} are supported")
    return poly.vertices.copy()


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


def _reduced_points(points, max_vertices: int) -> np.ndarray:
    """The vertices of conv(points), thinned to at most ``max_vertices`` by farthest-point sampling."""
    from scipy.spatial import ConvexHull, QhullError

    pts = _check_points(points)
    try:
        pts = pts[ConvexHull(pts).vertices]
    except (QhullError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise HullError(f"hull is degenerate (flat or collinear points): {first}") from None
    if len(pts) > max_vertices:
        pts = pts[farthest_point_subset(pts, max_vertices)]
    return pts


def reduce_to_hull(points, *, max_vertices: int = MAX_HULL_VERTICES) -> np.ndarray:
    """Hull vertices of a (mesh) point set, simplified to at most ``max_vertices`` vertices."""
    return hull_vertices(_reduced_points(points, max_vertices), max_vertices=max_vertices)


def usable_hull(points, *, max_vertices: int = MAX_HULL_VERTICES) -> np.ndarray:
    """Vertices of conv(points), reduced and cleaned until ``hull_vertices`` accepts them (module docstring)."""
    from scipy.spatial import ConvexHull, QhullError

    pts = _reduced_points(points, max_vertices)
    extent = float(np.ptp(pts, axis=0).max())
    last = None
    for level in (None, 1e-6, 1e-5, 1e-4, 1e-3):
        try:
            candidate = pts if level is None else pts[ConvexHull(pts, qhull_options=f"Qt C-{level * extent:.6e}").vertices]
            return hull_vertices(candidate, max_vertices=max_vertices)
        except (HullError, QhullError, ValueError) as exc:
            last = exc
    while len(pts) > 4:
        volumes = []
        for i in range(len(pts)):
            try:
                volumes.append(ConvexHull(np.delete(pts, i, axis=0)).volume)
            except (QhullError, ValueError):
                volumes.append(-1.0)
        pts = np.delete(pts, int(np.argmax(volumes)), axis=0)
        try:
            return hull_vertices(pts, max_vertices=max_vertices)
        except HullError as exc:
            last = exc
    raise HullError(f"no usable hull: {last}")
