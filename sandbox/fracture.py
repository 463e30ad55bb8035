"""Fracture: one body -> convex pieces that carry its mass and momentum exactly.

Host-side (numpy/scipy/trimesh), on ``BodySpec``s; ``World.fracture`` swaps the
pieces in through the world's rebuild.

**Pieces.** A compound body (two or more shapes: a CoACD-decomposed mesh, or a
scene compound) breaks into its shapes, each carrying the mass properties the
loader stored for it (``ShapeSpec.piece_mass`` ...; for a mesh, the mesh's
material inside that hull, see ``scene/decompose.py``). A convex body (one
shape) is cut into ``pieces`` Voronoi cells: seeds are drawn inside it with a
seeded generator (best of 8 uniform candidates, farthest from the seeds so far,
so no two seeds crowd), and cell i is the body's polytope clipped by the
bisector plane of every pair (i, j) (``polytope.clip_convex``). Cells share
their faces exactly, so they partition the body: volumes, centres of mass and
inertia tensors sum to the parent's up to rounding. Boxes and hulls are cut as
they are; a sphere or capsule is first replaced by a polytope of 42 / 50
vertices (an icosphere, split at the equator for a capsule) scaled radially by
(sphere volume / icosphere volume)^(1/3).

**Velocities.** The pieces keep the parent's rigid velocity field: piece p at
centre of mass x_p gets v_p = v + w x (x_p - x_c) and spin w, with the parent's
orientation and its own inertia. Momentum is then conserved exactly, because

    sum m_p v_p = M v + w x sum m_p (x_p - x_c) = M v,
    sum [m_p (x_p - x_c) x v_p + I_p w] = [sum I_p + m_p (|r_p|^2 E - r_p r_p^T)] w = I w

whenever the pieces partition the parent (sum m_p r_p = 0 and the
parallel-axis sum equals I). Where they do not exactly (a sphere's polytope has
a slightly different inertia than the sphere; a compound built by hand without
stored piece masses; a cell simplified to the engine's 64-vertex limit), the
field is refit instead of the momentum being let go: v' = P / M about the
pieces' own centre of mass c', and w' from I' w' = I w - M (c' - x_c) x v, with
I' the pieces' inertia about c'. That conserves P and L exactly (to float64
rounding) for any pieces, equals (v, w) for an exact partition, and the result
reports how far the pieces were from exact (``FractureResult``).

**Outward impulse.** ``impulse`` [N s] is the sum of the magnitudes of the
impulses that push the pieces apart. Piece p receives J_p = k m_p r_p (r_p from
the pieces' centre of mass), a uniform expansion dv_p = k r_p: these sum to zero
force and zero torque (r_p x r_p = 0), so momentum stays conserved, like an
internal explosion; the kinetic energy grows by sum |J_p|^2 / (2 m_p).

Pieces are not breakable themselves, so a fracture never cascades without end.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .errors import SandboxError
from .polytope import clip_convex
from .scene.hull import HullError, usable_hull
from .scene.massprops import MassProperties, combine, hull_mass_properties, shape_mass_properties, transformed
from .scene.rotations import quat_to_matrix
from .scene.spec import MAX_PIECES, RESISTANCE_KEYS, BodySpec, ShapeSpec

EXACT_TOLERANCE = 1e-9
"""[1] Pieces whose summed mass, centre of mass (relative to the body's size) and inertia
(relative to its norm) match the parent's to this count as an exact partition."""
SEED_CANDIDATES = 8
"""Uniform candidates drawn per Voronoi seed; the one farthest from earlier seeds is kept."""


class FractureError(SandboxError):
    """A body cannot be fractured; it stays whole, and the message says why."""


@dataclass
class FractureResult:
    bodies: list  # the pieces (BodySpecs), piece 0 first
    exact: bool  # the pieces partition the parent's mass distribution (module docstring)
    com_offset: float  # [m] distance between the pieces' centre of mass and the parent's
    inertia_mismatch: float  # [1] |I' - I| / |I| about the respective centres of mass
    mass_mismatch: float  # [1] |sum m_p - M| / M before the masses were scaled to M


# ---------------------------------------------------------------------------- convex outlines
def _icosphere() -> np.ndarray:
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
    scale = (4.0 / 3.0 * np.pi / float(m.volume)) ** (1.0 / 3.0)
    return np.asarray(m.vertices, dtype=np.float64) * scale


def convex_outline(shape: ShapeSpec) -> tuple[np.ndarray, bool]:
    """Polytope vertices of one shape in its shape frame, and whether they are the shape exactly."""
    if shape.kind == "box":
        h = np.asarray(shape.half_extents, dtype=np.float64)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h, True
    if shape.kind == "hull":
        return np.asarray(shape.vertices, dtype=np.float64), True
    ball = _icosphere() * float(shape.radius)
    if shape.kind == "sphere":
        return ball, False
    if shape.kind == "capsule":
        h = float(shape.half_height)
        top, bottom = ball[ball[:, 2] >= -1e-12], ball[ball[:, 2] <= 1e-12]
        return np.vstack([top + [0.0, 0.0, h], bottom - [0.0, 0.0, h]]), False
    raise FractureError(f"cannot fracture a shape of kind {shape.kind!r}")


def _to_body_frame(points: np.ndarray, shape: ShapeSpec) -> np.ndarray:
    rot = quat_to_matrix(shape.local_orientation)
    return points @ rot.T + np.asarray(shape.local_position, dtype=np.float64)


# ---------------------------------------------------------------------------- Voronoi cells
def voronoi_seeds(vertices: np.ndarray, count: int, seed: int) -> np.ndarray:
    """``count`` points strictly inside conv(vertices), spread by best-candidate sampling."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    inset = 1e-6 * float(np.ptp(vertices, axis=0).max())
    rng = np.random.default_rng(seed)
    seeds: list[np.ndarray] = []
    while len(seeds) < count:
        candidates = []
        for _ in range(1000):
            p = rng.uniform(lo, hi, size=(64, 3))
            inside = p[np.all(p @ hull.equations[:, :3].T + hull.equations[:, 3] < -inset, axis=1)]
            candidates.extend(inside[: SEED_CANDIDATES - len(candidates)])
            if len(candidates) >= SEED_CANDIDATES:
                break
        if not candidates:
            raise FractureError("could not place Voronoi seeds inside the body (it is too thin)")
        cand = np.asarray(candidates)
        if seeds:
            d = np.linalg.norm(cand[:, None, :] - np.asarray(seeds)[None, :, :], axis=2).min(axis=1)
            seeds.append(cand[int(np.argmax(d))])
        else:
            seeds.append(cand[0])
    return np.asarray(seeds)


def voronoi_cells(vertices: np.ndarray, seeds: np.ndarray) -> list[np.ndarray]:
    """The Voronoi cell of each seed inside conv(vertices), as vertex arrays (module docstring)."""
    cells = []
    for i, s in enumerate(seeds):
        cell = vertices
        for j, t in enumerate(seeds):
            if j == i or cell is None:
                continue
            n = t - s
            n = n / np.linalg.norm(n)
            cell = clip_convex(cell, n, float(n @ (0.5 * (s + t))))
        if cell is None:
            raise FractureError(f"Voronoi cell {i} came out empty (seeds too close together)")
        cells.append(cell)
    return cells


# ---------------------------------------------------------------------------- pieces
def _compound_parts(body: BodySpec) -> list[tuple[ShapeSpec, MassProperties]]:
    """Each shape of a compound with its share of the mass (body frame)."""
    if all(s.piece_mass is not None for s in body.shapes):
        return [(s, MassProperties(float(s.piece_mass), np.asarray(s.piece_com, dtype=np.float64),
                                   np.asarray(s.piece_inertia, dtype=np.float64))) for s in body.shapes]
    # no stored shares (a BodySpec built by hand): uniform density over the shapes' own volumes
    unit = [transformed(shape_mass_properties(s, 1.0), s.local_position, s.local_orientation) for s in body.shapes]
    rho = body.mass / sum(p.mass for p in unit)
    return [(s, p.scaled(rho)) for s, p in zip(body.shapes, unit)]


def _convex_parts(body: BodySpec, count: int, seed: int, min_piece_size: float) -> tuple[list, bool]:
    (shape,) = body.shapes
    outline, exact = convex_outline(shape)
    outline = _to_body_frame(outline, shape)
    whole = hull_mass_properties(outline, 1.0)
    typical = (whole.mass / count) ** (1.0 / 3.0)
    if typical < min_piece_size:
        raise FractureError(f"too small to split into {count} pieces: a piece would be about {typical * 1e3:.3g} mm "
                            f"across, and Settings.fracture_min_piece_size is {min_piece_size * 1e3:.3g} mm "
                            "(ask for fewer pieces, or lower the setting)")
    cells = voronoi_cells(outline, voronoi_seeds(outline, count, seed))
    rho = body.mass / whole.mass
    parts = []
    for k, cell in enumerate(cells):
        try:
            usable = usable_hull(cell)
        except HullError as exc:
            raise FractureError(f"Voronoi cell {k} is not a usable hull ({exc})") from None
        mp = hull_mass_properties(usable, rho)
        size = (mp.mass / rho) ** (1.0 / 3.0)
        if size < min_piece_size:
            raise FractureError(f"too small to split into {count} pieces with seed {seed}: piece {k} would be "
                                f"{size * 1e3:.3g} mm across (cube root of its volume), below "
                                f"Settings.fracture_min_piece_size = {min_piece_size * 1e3:.3g} mm")
        parts.append((ShapeSpec("hull", vertices=usable), mp))
    return parts, exact


def check_arguments(pieces, seed, impulse) -> None:
    """Raise FractureError unless pieces is 2..MAX_PIECES, seed an integer >= 0, impulse finite >= 0."""
    def integer(x):
        return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_))

    if not integer(pieces) or not 2 <= pieces <= MAX_PIECES:
        raise FractureError(f"pieces must be an integer from 2 to {MAX_PIECES} (MAX_PIECES), got {pieces!r}")
    if not integer(seed) or seed < 0:
        raise FractureError(f"seed must be an integer >= 0, got {seed!r}")
    if not (isinstance(impulse, (int, float, np.integer, np.floating)) and not isinstance(impulse, (bool, np.bool_))
            and np.isfinite(impulse) and impulse >= 0):
        raise FractureError(f"impulse must be a finite number >= 0 [N s], got {impulse!r}")


def fracture_body(body: BodySpec, *, pieces: int = 8, seed: int = 0, impulse: float = 0.0,
                  min_piece_size: float = 0.01) -> FractureResult:
    """The pieces of ``body`` (module docstring); raises FractureError and leaves it alone when it cannot."""
    if body.static:
        raise FractureError("it is static")
    check_arguments(pieces, seed, impulse)
    if len(body.shapes) >= 2:
        parts = [(dataclasses.replace(s, piece_mass=None, piece_com=None, piece_inertia=None), mp)
                 for s, mp in _compound_parts(body)]
        exact = all(s.piece_mass is not None for s in body.shapes)
    else:
        parts, exact = _convex_parts(body, int(pieces), int(seed), float(min_piece_size))
    return _assemble(body, parts, exact, float(impulse))


def _assemble(body: BodySpec, parts: list, exact: bool, impulse: float) -> FractureResult:
    """Place the pieces in the world and give them the parent's momentum (module docstring)."""
    mass = float(body.mass)
    total = sum(mp.mass for _, mp in parts)
    mass_mismatch = abs(total - mass) / mass
    if mass_mismatch > EXACT_TOLERANCE:
        parts = [(s, mp.scaled(mass / total)) for s, mp in parts]
        exact = False
    merged = combine([mp for _, mp in parts])  # body frame: c' and I' about c'
    size = max(float(np.linalg.norm(mp.com)) for _, mp in parts) or 1.0
    com_offset = float(np.linalg.norm(merged.com))
    inertia_mismatch = float(np.linalg.norm(merged.inertia - body.inertia) / np.linalg.norm(body.inertia))
    exact = exact and com_offset <= EXACT_TOLERANCE * size and inertia_mismatch <= EXACT_TOLERANCE

    rot = quat_to_matrix(body.orientation)
    x_c = np.asarray(body.position, dtype=np.float64)
    v = np.asarray(body.linear_velocity, dtype=np.float64)
    w_body = rot.T @ np.asarray(body.angular_velocity, dtype=np.float64)
    # refit about the pieces' centre of mass c' (equals (v, w) for an exact partition)
    w_fit = rot @ np.linalg.solve(merged.inertia, body.inertia @ w_body - mass * np.cross(merged.com, rot.T @ v))
    x_fit = x_c + rot @ merged.com
    arms = [x_c + rot @ mp.com - x_fit for _, mp in parts]
    reach = sum(mp.mass * float(np.linalg.norm(r)) for (_, mp), r in zip(parts, arms))
    k = impulse / reach if impulse > 0 and reach > 0 else 0.0

    out = []
    for p, ((shape, mp), r) in enumerate(zip(parts, arms)):
        piece_shape = dataclasses.replace(shape, local_position=np.asarray(shape.local_position, np.float64) - mp.com)
        if piece_shape.kind == "hull" and len(body.shapes) == 1:
            piece_shape = dataclasses.replace(piece_shape, vertices=np.asarray(shape.vertices) - mp.com,
                                              local_position=np.zeros(3))
        out.append(BodySpec(
            shapes=[piece_shape],
            position=x_fit + r,
            orientation=np.asarray(body.orientation, dtype=np.float64).copy(),
            linear_velocity=v + np.cross(w_fit, r) + k * r,
            angular_velocity=w_fit.copy(),
            mass=float(mp.mass),
            inertia=0.5 * (mp.inertia + mp.inertia.T),
            static=False,
            friction=body.friction,
            restitution=body.restitution,
            **{key: getattr(body, key) for key in RESISTANCE_KEYS},
            name=f"{body.name}.{p}" if body.name else None,
        ))
    return FractureResult(out, exact, com_offset, inertia_mismatch, mass_mismatch)


def piece_count(body: BodySpec, pieces: int) -> int:
    """How many bodies a fracture of ``body`` makes (its shapes for a compound, else ``pieces``)."""
    return len(body.shapes) if len(body.shapes) >= 2 else int(pieces)
