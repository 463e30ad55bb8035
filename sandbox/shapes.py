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


import numpy as np
import taichi as ti

from .field_upload import write_rows
from .polytope import (  # noqa: F401  (re-exported: kinds and builders live with the host geometry)
    BOX, CAPSULE, HULL, KIND_NAMES, MAX_POLY_VERTS, PLANE, POLYTOPE_KINDS, SPHERE, TRIANGLE, GeometryError, Polytope,
    box_polytope, hull_polytope, triangle_polytope, triangle_polytopes,
)


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
        # per loop entry k of a face: the side plane through loop edge k -> k + 1, outward unit
        # normal (xyz) and offset (w), so clipping reads a plane instead of rebuilding it
        self.side = ti.Vector.field(4, ti.f32, nl)
        self.edge_vert = ti.Vector.field(2, ti.i32, ne)
        self.edge_face = ti.Vector.field(2, ti.i32, ne)

    @staticmethod
    def sizes(polytopes: list) -> tuple:
        return (len(polytopes), sum(len(p.vertices) for p in polytopes), sum(len(p.face_loops) for p in polytopes),
                sum(sum(len(l) for l in p.face_loops) for p in polytopes), sum(len(p.edges) for p in polytopes))

    def upload(self, polytopes: list, first: int = 0, offsets: tuple = (0, 0, 0, 0)) -> tuple:
        """Write ``polytopes`` from polytope id ``first`` on, their data from ``offsets``
        (verts, faces, loops, edges). Returns the offsets after them, for appending."""
        columns, after = self.upload_columns(polytopes, first, offsets)
        write_rows(columns)
        return after

    def upload_columns(self, polytopes: list, first: int = 0, offsets: tuple = (0, 0, 0, 0)) -> tuple:
        """``upload``'s rows as field_upload.write_rows columns, and the offsets after them (build.upload
        writes them with the other buffers' in one launch)."""
        if not polytopes:
            return [], offsets
        vs, fs, ls, es = offsets
        rows, verts, fn, fo, flc, loops, ev, ef, cen = [], [], [], [], [], [], [], [], []
        for p in polytopes:
            rows.append((vs, len(p.vertices), fs, len(p.face_loops), es, len(p.edges)))
            verts.append(p.vertices)
            cen.append(p.centroid)
            fn.append(p.face_normals)
            fo.append(p.face_offsets)
            for loop in p.face_loops:
                flc.append(len(loop))
                loops.append(np.asarray(loop) + vs)
            ev.append(p.edges + vs)
            ef.append(p.edge_faces + fs)
            vs += len(p.vertices)
            fs += len(p.face_loops)
            es += len(p.edges)
        rows = np.asarray(rows, np.int32)
        flc = np.asarray(flc, np.int64)
        fls = offsets[2] + np.concatenate(([0], np.cumsum(flc)[:-1]))
        ls = offsets[2] + int(flc.sum())
        all_verts, all_normals, loop = np.concatenate(verts), np.concatenate(fn), np.concatenate(loops)
        columns = [
            (self.vert_start, first, rows[:, 0]), (self.vert_count, first, rows[:, 1]),
            (self.face_start, first, rows[:, 2]), (self.face_count, first, rows[:, 3]),
            (self.edge_start, first, rows[:, 4]), (self.edge_count, first, rows[:, 5]),
            (self.centroid, first, np.asarray(cen)),
            (self.vert, offsets[0], all_verts),
            (self.face_normal, offsets[1], all_normals), (self.face_offset, offsets[1], np.concatenate(fo)),
            (self.face_loop_start, offsets[1], fls), (self.face_loop_count, offsets[1], flc),
            (self.loop, offsets[2], loop),
            (self.side, offsets[2], _side_planes(all_verts, all_normals, loop - offsets[0], flc)),
            (self.edge_vert, offsets[3], np.concatenate(ev)), (self.edge_face, offsets[3], np.concatenate(ef)),
        ]
        self.count = first + len(polytopes)
        return columns, (vs, fs, ls, es)


def _side_planes(vertices: np.ndarray, normals: np.ndarray, loop: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """(k, 4) for every loop entry k: unit outward normal and offset of the side plane through
    its face's edge k -> k + 1 (loops are counter-clockwise seen from outside, so
    (v1 - v0) x n points out of the face). ``loop``: the faces' loops one after another,
    indices into ``vertices``; ``counts``: each face's loop length; ``normals``: one per face."""
    face = np.repeat(np.arange(len(counts)), counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    position = np.arange(len(loop))
    following = start + (position - start + 1) % np.repeat(counts, counts)
    v0, v1 = vertices[loop], vertices[loop[following]]
    s = np.cross(v1 - v0, normals[face])
    s /= np.maximum(np.linalg.norm(s, axis=1, keepdims=True), 1.0e-30)
    return np.c_[s, (s * v0).sum(axis=1)]


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
        write_rows(self.upload_columns(arrays, planes, dynamic_ids))
        self.finish_upload(len(arrays["kind"]), len(planes["normal"]), len(dynamic_ids))

    def upload_columns(self, arrays: dict[str, np.ndarray], planes: dict[str, np.ndarray],
                       dynamic_ids: np.ndarray) -> list:
        """``upload``'s rows as field_upload.write_rows columns (build.upload writes them with
        the other buffers' in one launch)."""
        columns = [(getattr(self, name), 0, values) for name, values in arrays.items()]
        columns.append((self.dynamic_ids, 0, dynamic_ids))
        columns += [(getattr(self, "plane_" + name), 0, planes[name])
                    for name in ("normal", "offset", "body", "friction", "restitution")]
        return columns

    def finish_upload(self, shapes: int, planes: int, dynamic: int) -> None:
        """The counts, once ``upload_columns``' rows are written."""
        self.count[None] = shapes
        self.dynamic_count[None] = dynamic
        self.plane_count[None] = planes
