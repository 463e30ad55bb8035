"""Render meshes for bodies, grouped so that one batched (instanced) node draws every body of
one shape: a pile of equal boxes is one node whatever its size.

Boxes, spheres and capsules share unit meshes scaled per instance, so random debris of many
sizes still needs one node per kind; hulls and compounds are unique shapes (one node each).
"""

from __future__ import annotations

import hashlib
from typing import NamedTuple

import numpy as np
import trimesh

from sandbox import IDENTITY, BodySpec, ShapeSpec, quat_to_matrix


class RenderMesh(NamedTuple):
    vertices: np.ndarray  # (V, 3) float32, body frame (unit size for scaled kinds)
    faces: np.ndarray  # (F, 3) uint32


def body_shape(body: BodySpec) -> tuple[tuple, np.ndarray]:
    """(key, per-instance scale (3,)) of a body: bodies with equal keys share one mesh."""
    if len(body.shapes) == 1 and _is_identity(body.shapes[0]):
        s = body.shapes[0]
        if s.kind == "box":
            return ("box",), 2.0 * np.asarray(s.half_extents, dtype=np.float64)
        if s.kind == "sphere":
            return ("sphere",), np.full(3, s.radius)
        if s.kind == "capsule":
            return ("capsule", round(s.half_height / s.radius, 3)), np.full(3, s.radius)
    return ("mesh", _digest(body.shapes)), np.ones(3)


def shape_mesh(key: tuple, body: BodySpec) -> RenderMesh:
    """The mesh for ``key`` (``body`` is any body with that key)."""
    if key == ("box",):
        mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    elif key == ("sphere",):
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    elif key[0] == "capsule":
        mesh = trimesh.creation.capsule(height=2.0 * key[1], radius=1.0, count=[16, 8])
    else:
        mesh = trimesh.util.concatenate([_placed_mesh(s) for s in body.shapes])
    return RenderMesh(np.asarray(mesh.vertices, dtype=np.float32), np.asarray(mesh.faces, dtype=np.uint32))


def _placed_mesh(shape: ShapeSpec) -> trimesh.Trimesh:
    if shape.kind == "box":
        mesh = trimesh.creation.box(extents=2.0 * np.asarray(shape.half_extents))
    elif shape.kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=shape.radius)
    elif shape.kind == "capsule":
        mesh = trimesh.creation.capsule(height=2.0 * shape.half_height, radius=shape.radius, count=[16, 8])
    else:
        mesh = trimesh.convex.convex_hull(np.asarray(shape.vertices, dtype=np.float64))
    transform = np.eye(4)
    transform[:3, :3] = quat_to_matrix(shape.local_orientation)
    transform[:3, 3] = shape.local_position
    mesh.apply_transform(transform)
    return mesh


def _is_identity(shape: ShapeSpec) -> bool:
    return bool(np.allclose(shape.local_position, 0.0) and np.allclose(shape.local_orientation, IDENTITY))


def _digest(shapes: list[ShapeSpec]) -> str:
    h = hashlib.sha1()
    for s in shapes:
        h.update(s.kind.encode())
        for part in (s.radius, s.half_height, s.half_extents, s.vertices, s.local_position, s.local_orientation):
            if part is not None:
                h.update(np.asarray(part, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def static_meshes(scene, half_size: float) -> list[tuple[str, np.ndarray, np.ndarray, tuple]]:
    """(name, vertices, faces, colour) of everything that never moves: planes as square
    slabs ``2 * half_size`` wide, triangle meshes (terrain) as they are; static bodies are
    drawn with the dynamic ones (they are in the same body arrays)."""
    out = []
    for k, plane in enumerate(scene.planes):
        n = np.asarray(plane.normal, dtype=np.float64)
        slab = trimesh.creation.box(extents=(2.0 * half_size, 2.0 * half_size, 0.02))
        slab.apply_translation((0.0, 0.0, -0.01))
        align = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], n)
        slab.apply_transform(align)
        slab.apply_translation(n * plane.offset)
        out.append((f"/static/plane_{k}", slab.vertices, slab.faces, (205, 200, 190)))
    for k, mesh in enumerate(scene.meshes):
        out.append((f"/static/mesh_{k}", np.asarray(mesh.vertices), np.asarray(mesh.triangles), (150, 170, 150)))
    return out
