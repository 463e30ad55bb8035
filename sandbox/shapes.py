"""Collision shapes: kinds, convex polytopes (boxes, hulls, mesh triangles) and their pools.

Every convex piece is one of two families, which keeps the narrowphase small:

* *rounded cores*: a sphere is a point with a radius, a capsule a segment (along
  its local z axis, half length ``half_height``) with a radius;
* *polytopes*: boxes, convex hulls and static mesh triangles share one vertex /
  face / edge pool, so box-box, box-hull, hull-hull and anything-triangle all run
  the same SAT-and-clip code (Gregorius, "The Separating Axis Test between Convex
  Polyhedra", GDC 2013). Faces are merged coplanar polygons, not triangles, so a
  box face is one quad and face-face manifolds come out as 4 stable points.

A triangle is a polytope with two faces (front, back) and three edges; the
narrowphase treats it one-sided (only its front normal pushes).

Compound bodies are simply several shapes pointing at one body (``shape_body``),
each with a pose relative to the body's centre of mass.
"""


from dataclasses import dataclass

import numpy as np
import taichi as ti

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


@ti.data_oriented
class PolytopePool:
    """All polytopes of a world in flat Taichi fields (structure of arrays).

    Indices stored in loops and edges are *global* (into ``vert`` / ``face_*``),
    so a kernel needs only the polytope id to walk one polytope. Fields are
    allocated for a capacity class and filled by ``upload`` (buffers.py reuses
    pools across worlds so kernels are not recompiled).
    """

    def __init__(self, polys: int, verts: int, faces: int, loops: int, edges: int):
        n, nv, nf, nl, ne = (max(1, x) for x in (polys, verts, faces, loops, edges))
        self.capacity = (polys, verts, faces, loops, edges)
        self.count = 0
        self.vert_start = ti.field(ti.i32, n)
        self.vert_count = ti.field(ti.i32, n)
        self.face_start = ti.field(ti.i32, n)
        self.face_count = ti.field(ti.i32, n)
        self.edge_start = ti.field(ti.i32, n)
        self.edge_count = ti.field(ti.i32, n)
        self.centroid = ti.Vector.field(3, ti.f32, n)
        self.vert = ti.Vector.field(3, ti.f32, nv)
        self.face_normal = ti.Vector.field(3, ti.f32, nf)
        self.face_offset = ti.field(ti.f32, nf)
        self.face_loop_start = ti.field(ti.i32, nf)
        self.face_loop_count = ti.field(ti.i32, nf)
        self.loop = ti.field(ti.i32, nl)
        self.edge_vert = ti.Vector.field(2, ti.i32, ne)
        self.edge_face = ti.Vector.field(2, ti.i32, ne)

    @staticmethod
    def sizes(polytopes: list) -> tuple:
        return (len(polytopes), sum(len(p.vertices) for p in polytopes), sum(len(p.face_loops) for p in polytopes),
                sum(sum(len(l) for l in p.face_loops) for p in polytopes), sum(len(p.edges) for p in polytopes))

    def upload(self, polytopes: list, first: int = 0, offsets: tuple = (0, 0, 0, 0)) -> tuple:
        """Write ``polytopes`` from polytope id ``first`` on, their data from ``offsets``
        (verts, faces, loops, edges). Returns the offsets after them, for appending."""
        if not polytopes:
            return offsets
        vs, fs, ls, es = offsets
        rows, verts, fn, fo, fls, flc, loops, ev, ef, cen = [], [], [], [], [], [], [], [], [], []
        for p in polytopes:
            rows.append((vs, len(p.vertices), fs, len(p.face_loops), es, len(p.edges)))
            verts.append(p.vertices)
            cen.append(p.centroid)
            fn.append(p.face_normals)
            fo.append(p.face_offsets)
            for loop in p.face_loops:
                fls.append(ls)
                flc.append(len(loop))
                loops.append(np.asarray(loop) + vs)
                ls += len(loop)
            ev.append(p.edges + vs)
            ef.append(p.edge_faces + fs)
            vs += len(p.vertices)
            fs += len(p.face_loops)
            es += len(p.edges)
        rows = np.asarray(rows, np.int32)
        _write(self.vert_start, first, rows[:, 0])
        _write(self.vert_count, first, rows[:, 1])
        _write(self.face_start, first, rows[:, 2])
        _write(self.face_count, first, rows[:, 3])
        _write(self.edge_start, first, rows[:, 4])
        _write(self.edge_count, first, rows[:, 5])
        _write(self.centroid, first, np.asarray(cen, np.float32))
        _write(self.vert, offsets[0], np.concatenate(verts).astype(np.float32))
        _write(self.face_normal, offsets[1], np.concatenate(fn).astype(np.float32))
        _write(self.face_offset, offsets[1], np.concatenate(fo).astype(np.float32))
        _write(self.face_loop_start, offsets[1], np.asarray(fls, np.int32))
        _write(self.face_loop_count, offsets[1], np.asarray(flc, np.int32))
        _write(self.loop, offsets[2], np.concatenate(loops).astype(np.int32))
        _write(self.edge_vert, offsets[3], np.concatenate(ev).astype(np.int32))
        _write(self.edge_face, offsets[3], np.concatenate(ef).astype(np.int32))
        self.count = first + len(polytopes)
        return (vs, fs, ls, es)


def _write(field, first: int, values: np.ndarray) -> None:
    """Write rows ``first .. first+len(values)`` of a field, leaving the rest untouched."""
    full = field.to_numpy()
    full[first:first + len(values)] = values
    field.from_numpy(full)


@ti.data_oriented
class ShapeTable:
    """Per-shape parameters: which body, where on it, what kind, what material.

    ``local_aabb_center/half`` bound the shape in its own frame; the broadphase
    turns them into a world AABB with one rotation (|R| h), exact for boxes.
    Static shapes (mesh triangles, static bodies) are listed in ``static_ids``
    and sit in a grid built once; dynamic ones in ``dynamic_ids``.
    """

    def __init__(self, capacity: int, plane_capacity: int):
        c = max(1, capacity)
        self.capacity = c
        self.count = ti.field(ti.i32, ())
        self.kind = ti.field(ti.i32, c)
        self.body = ti.field(ti.i32, c)
        self.local_pos = ti.Vector.field(3, ti.f32, c)
        self.local_rot = ti.Vector.field(4, ti.f32, c)
        self.radius = ti.field(ti.f32, c)
        self.half_height = ti.field(ti.f32, c)
        self.poly = ti.field(ti.i32, c)
        self.bound = ti.field(ti.f32, c)
        self.friction = ti.field(ti.f32, c)
        self.restitution = ti.field(ti.f32, c)
        self.aabb_center = ti.Vector.field(3, ti.f32, c)
        self.aabb_half = ti.Vector.field(3, ti.f32, c)
        self.dynamic_count = ti.field(ti.i32, ())
        self.dynamic_ids = ti.field(ti.i32, c)
        pc = max(1, plane_capacity)
        self.plane_count = ti.field(ti.i32, ())
        self.plane_normal = ti.Vector.field(3, ti.f32, pc)
        self.plane_offset = ti.field(ti.f32, pc)
        self.plane_body = ti.field(ti.i32, pc)
        self.plane_friction = ti.field(ti.f32, pc)
        self.plane_restitution = ti.field(ti.f32, pc)

    def upload(self, arrays: dict[str, np.ndarray], planes: dict[str, np.ndarray], dynamic_ids: np.ndarray) -> None:
        n = len(arrays["kind"])
        for name, values in arrays.items():
            _write(getattr(self, name), 0, values)
        self.count[None] = n
        _write(self.dynamic_ids, 0, dynamic_ids)
        self.dynamic_count[None] = len(dynamic_ids)
        m = len(planes["normal"])
        for name in ("normal", "offset", "body", "friction", "restitution"):
            _write(getattr(self, "plane_" + name), 0, planes[name])
        self.plane_count[None] = m
