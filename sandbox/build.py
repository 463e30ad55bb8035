"""Turn a validated Scene into host arrays (``host_world``) and upload them into a
pooled BufferSet (``upload``): bodies, shapes, polytope pool, static grid.

This runs once per world on the host (numpy), never inside a step. Scene bodies
keep their order (row i of ``World.state()`` is ``scene.bodies[i]``); one extra
static body at the origin carries the planes and mesh triangles. Identical
polytopes (e.g. 5000 equal boxes) are stored once. Triangles are stored about
their centroid so float32 stays precise far from the origin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import taichi as ti

from .buffers import BufferSet, Capacities
from .field_upload import write_rows
from .scene.spec import Scene
from .settings import Settings
from .shapes import (
    BOX, CAPSULE, HULL, PLANE, SPHERE, TRIANGLE, PolytopePool, box_polytope, hull_polytope, triangle_polytopes,
)
from .static_grid import build_static_grid, static_aabbs, static_entry_count
from .step_kernels import after_upload


RESERVE_HULL = (24, 14, 72, 36)
"""Vertices, faces, face-loop entries and edges reserved per fracture piece: a Voronoi cell of a box
cut by 7 bisector planes has at most 13 faces, 22 vertices and 33 edges (Euler: V - E + F = 2)."""


@dataclass
class HostWorld:
    """Everything a world uploads, as host arrays, plus its capacity needs."""

    body_arrays: dict
    shape_arrays: dict
    plane_arrays: dict
    dynamic_ids: np.ndarray
    static_ids: np.ndarray
    polytopes: list
    kinds: tuple
    cell_size: float
    static_entries: int
    n_dynamic: int
    has_restitution: bool = False  # some shape or plane has restitution > 0
    has_friction: bool = False  # some shape or plane has a friction coefficient > 0
    has_gyroscopic: bool = False  # some dynamic body's inertia is not a multiple of the identity
    has_damping: bool = False  # some dynamic body has linear or angular damping > 0
    has_rolling_friction: bool = False  # some body has rolling or torsional friction > 0
    mass_spread: float = 1.0  # the heaviest dynamic body's mass over the lightest's (effects.py)

    def capacities(self, pairs: int | None = None, grid_entries: int | None = None, reserve_pieces: int = 0) -> Capacities:
        """Capacity classes for this world, with room for ``reserve_pieces`` added bodies (fracture
        pieces, a scene's scripted drops: each a new body, shape and hull of up to RESERVE_HULL
        vertices / faces / loop entries / edges, with its share of grid entries and pairs)."""
        sizes = PolytopePool.sizes(self.polytopes)
        r = int(reserve_pieces)
        hv, hf, hl, he = RESERVE_HULL
        return Capacities.for_counts(
            bodies=len(self.body_arrays["inv_mass"]) + r, shapes=len(self.shape_arrays["kind"]) + r,
            planes=len(self.plane_arrays["normal"]), polys=sizes[0] + r, poly_verts=sizes[1] + r * hv,
            poly_faces=sizes[2] + r * hf, poly_loops=sizes[3] + r * hl, poly_edges=sizes[4] + r * he,
            static_hash=2 * self.static_entries,
            static_entries=self.static_entries, grid_entries=grid_entries or (16 * (self.n_dynamic + r) + 1024),
            pairs=pairs or (12 * (self.n_dynamic + r) + 1024),
        )


def host_world(scene: Scene, settings: Settings) -> HostWorld:
    n_scene = len(scene.bodies)
    n_bodies = n_scene + 1  # + the static carrier of planes and meshes
    ground = n_scene
    polys: list = []
    poly_index: dict = {}

    def add_poly(key, make):
        if key is not None and key in poly_index:
            return poly_index[key]
        poly = make()
        polys.append(poly)
        idx = len(polys) - 1
        if key is not None:
            poly_index[key] = idx
        return idx

    rows = {k: [] for k in ("kind", "body", "local_pos", "local_rot", "radius", "half_height", "poly", "bound",
                            "friction", "restitution", "aabb_center", "aabb_half")}

    def add_shape(kind, body, lpos, lrot, radius, hh, poly, bound, fr, re, c, half):
        for k, v in zip(rows, (kind, body, lpos, lrot, radius, hh, poly, bound, fr, re, c, half)):
            rows[k].append(v)

    inv_mass = np.zeros(n_bodies)
    inertia = np.zeros((n_bodies, 3, 3))
    inv_inertia = np.zeros((n_bodies, 3, 3))
    pos = np.zeros((n_bodies, 3))
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (n_bodies, 1))
    lin_vel = np.zeros((n_bodies, 3))
    ang_vel = np.zeros((n_bodies, 3))
    damping = np.zeros((n_bodies, 2))  # [1/s] linear, angular (dynamic bodies)
    rolling = np.zeros((n_bodies, 2))  # [m] rolling, torsional
    dynamic_shapes = []
    for bi, body in enumerate(scene.bodies):
        pos[bi] = body.position
        q = np.asarray(body.orientation, dtype=np.float64)
        norm = np.linalg.norm(q)
        # a unit quaternion read back from the device is kept as it is, so a rebuild (add, remove,
        # fracture) leaves the other bodies' float32 state bit for bit unchanged
        rot[bi] = q if abs(norm - 1.0) < 1e-6 else q / norm
        if not body.static:
            inv_mass[bi] = 1.0 / body.mass
            inertia[bi] = body.inertia
            inv_inertia[bi] = np.linalg.inv(body.inertia)
            lin_vel[bi] = body.linear_velocity
            ang_vel[bi] = body.angular_velocity
            damping[bi] = body.linear_damping, body.angular_damping
        rolling[bi] = body.rolling_friction, body.torsional_friction
        for sh in body.shapes:
            lq = np.asarray(sh.local_orientation, dtype=np.float64)
            lq = lq / np.linalg.norm(lq)
            if sh.kind == "sphere":
                r = float(sh.radius)
                add_shape(SPHERE, bi, sh.local_position, lq, r, 0.0, -1, r, body.friction, body.restitution,
                          np.zeros(3), np.full(3, r))
            elif sh.kind == "capsule":
                r, hh = float(sh.radius), float(sh.half_height)
                add_shape(CAPSULE, bi, sh.local_position, lq, r, hh, -1, r + hh, body.friction, body.restitution,
                          np.zeros(3), np.array([r, r, r + hh]))
            elif sh.kind == "box":
                h = np.asarray(sh.half_extents, dtype=np.float64)
                pid = add_poly(("box", *np.round(h, 7)), lambda h=h: box_polytope(h))
                add_shape(BOX, bi, sh.local_position, lq, 0.0, 0.0, pid, float(np.linalg.norm(h)), body.friction,
                          body.restitution, np.zeros(3), h)
            elif sh.kind == "hull":
                v = np.asarray(sh.vertices, dtype=np.float64)
                pid = add_poly(None, lambda v=v: hull_polytope(v))
                pv = polys[pid].vertices
                lo, hi = pv.min(axis=0), pv.max(axis=0)
                add_shape(HULL, bi, sh.local_position, lq, 0.0, 0.0, pid, float(np.linalg.norm(pv, axis=1).max()),
                          body.friction, body.restitution, 0.5 * (lo + hi), 0.5 * (hi - lo))
            else:  # the loader only lets the kinds above through
                raise ValueError(f"unknown shape kind {sh.kind!r}")
            if not body.static:
                dynamic_shapes.append(len(rows["kind"]) - 1)
    for mesh in scene.meshes:  # every triangle at once: a terrain has ~18 000
        p = np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.triangles)]
        c = p.mean(axis=1)
        local = p - c[:, None, :]
        m, first_poly = len(p), len(polys)
        polys.extend(triangle_polytopes(local))
        lo, hi = p.min(axis=1) - c, p.max(axis=1) - c
        for key, values in (("kind", [TRIANGLE] * m), ("body", [ground] * m), ("local_pos", list(c)),
                            ("local_rot", [np.array([1.0, 0, 0, 0])] * m), ("radius", [0.0] * m),
                            ("half_height", [0.0] * m), ("poly", list(range(first_poly, first_poly + m))),
                            ("bound", list(np.linalg.norm(local, axis=2).max(axis=1))),
                            ("friction", [mesh.friction] * m), ("restitution", [mesh.restitution] * m),
                            ("aabb_center", list(0.5 * (lo + hi))), ("aabb_half", list(0.5 * (hi - lo) + 1e-4))):
            rows[key].extend(values)
    n_shapes = len(rows["kind"])
    arrays = {
        "kind": np.asarray(rows["kind"], np.int32),
        "body": np.asarray(rows["body"], np.int32),
        "local_pos": np.asarray(rows["local_pos"], np.float32).reshape(-1, 3),
        "local_rot": np.asarray(rows["local_rot"], np.float32).reshape(-1, 4),
        "radius": np.asarray(rows["radius"], np.float32),
        "half_height": np.asarray(rows["half_height"], np.float32),
        "poly": np.asarray(rows["poly"], np.int32),
        "bound": np.asarray(rows["bound"], np.float32),
        "friction": np.asarray(rows["friction"], np.float32),
        "restitution": np.asarray(rows["restitution"], np.float32),
        "aabb_center": np.asarray(rows["aabb_center"], np.float32).reshape(-1, 3),
        "aabb_half": np.asarray(rows["aabb_half"], np.float32).reshape(-1, 3),
    }
    planes = {
        "normal": np.asarray([p.normal for p in scene.planes], np.float32).reshape(-1, 3),
        "offset": np.asarray([p.offset for p in scene.planes], np.float32),
        "body": np.full(len(scene.planes), ground, np.int32),
        "friction": np.asarray([p.friction for p in scene.planes], np.float32),
        "restitution": np.asarray([p.restitution for p in scene.planes], np.float32),
    }
    body_arrays = {"inv_mass": inv_mass, "inertia": inertia, "inv_inertia": inv_inertia, "pos": pos, "rot": rot,
                   "lin_vel": lin_vel, "ang_vel": ang_vel, "damping": damping, "rolling": rolling}
    dyn = np.asarray(dynamic_shapes, np.int32)
    margin = settings.contact_margin
    diam = 2.0 * arrays["aabb_half"][dyn].max(axis=1) + 2.0 * margin if len(dyn) else np.array([1.0])
    cell = float(max(1.5 * np.median(diam), 1e-3))
    is_static_body = np.array([b.static for b in scene.bodies] + [True])
    static_ids = np.flatnonzero(is_static_body[arrays["body"]]) if n_shapes else np.zeros(0, np.int64)
    kinds = tuple(sorted(set(int(k) for k in arrays["kind"]) | ({PLANE} if len(scene.planes) else set())))
    host = HostWorld(body_arrays, arrays, planes, dyn, static_ids, polys, kinds, cell, 0, len(dyn))
    host.static_entries = static_entry_count(host, margin)
    host.has_restitution = bool(np.any(arrays["restitution"] > 0) or np.any(planes["restitution"] > 0))
    host.has_friction = bool(np.any(arrays["friction"] > 0) or np.any(planes["friction"] > 0))
    host.has_gyroscopic = any_anisotropic(inertia[inv_mass > 0])
    host.has_damping = bool(np.any(damping > 0))
    host.has_rolling_friction = bool(np.any(rolling > 0))
    host.mass_spread = mass_spread(inv_mass[inv_mass > 0])
    return host


def mass_spread(inv_masses: np.ndarray) -> float:
    """[1] The heaviest of these bodies' masses over the lightest's (1 for fewer than two)."""
    return float(inv_masses.max() / inv_masses.min()) if len(inv_masses) > 1 else 1.0


ISOTROPY_TOLERANCE = 1e-6
"""[1] An inertia within this fraction of a multiple of the identity counts as isotropic: its
gyroscopic torque w x (I w) is below float32 rounding of the rotation update."""


def any_anisotropic(inertias: np.ndarray) -> bool:
    """Does any of these (N, 3, 3) body-frame inertias have a gyroscopic term (not a sphere's
    or a cube's)?"""
    if len(inertias) == 0:
        return False
    mean = np.trace(inertias, axis1=1, axis2=2) / 3.0
    deviation = np.abs(inertias - mean[:, None, None] * np.eye(3)).max(axis=(1, 2))
    return bool(np.any(deviation > ISOTROPY_TOLERANCE * np.abs(mean)))


def upload(host: HostWorld, buffers: BufferSet, margin: float, placed: np.ndarray | None = None) -> None:
    """Fill a pooled BufferSet with a world's data, ``placed`` its bodies new to the world
    (Bodies.mark_placed), and reset its per-step scratch. The rows of bodies, shapes, polytopes and
    the static grid go in one write_rows launch: as one launch per buffer (and a ``fill`` or
    ``from_numpy`` per field), a process's first world loaded a dozen more kernel instances."""
    lo, hi = static_aabbs(host, margin)
    grid = build_static_grid(lo, hi, host.static_ids, host.cell_size, hash_size=buffers.bp.static_hash_size)
    polytope_columns, _ = buffers.pool.upload_columns(host.polytopes)
    write_rows(buffers.bodies.upload_columns(host.body_arrays)
               + buffers.shapes.upload_columns(host.shape_arrays, host.plane_arrays, host.dynamic_ids)
               + polytope_columns + buffers.bp.static_grid_columns(grid)
               + buffers.bodies.placed_columns(np.zeros(0, np.int64) if placed is None else placed))
    after_upload(buffers, margin, len(host.body_arrays["inv_mass"]), len(host.shape_arrays["kind"]),
                 len(host.plane_arrays["normal"]), len(host.dynamic_ids), host.cell_size, grid["cell_size"],
                 ti.math.vec3(grid["lo"]), ti.math.vec3(grid["hi"]))
