"""Scene generators: stacks, pyramids and grids of bodies, expanded into BodySpecs.

Each generator is deterministic: random draws come from one
``numpy.random.default_rng(seed)`` per ``[[generate]]`` entry, in a fixed order
(stated per generator), so a seed reproduces a scene exactly on any machine with
the same numpy. Positions and mass properties are computed for all bodies at
once (boxes analytically in one batch), so a 1000-body pile expands in a few
milliseconds; only then is one ``BodySpec`` made per body.

Generated bodies start at rest. Names, when a ``name`` prefix is given, are
``<prefix>_<i>`` with i counting from 0 in generation order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hull import hull_vertices
from .massprops import (
    box_mass_properties_batch,
    capsule_mass_properties,
    hull_mass_properties,
    sphere_mass_properties,
)
from .rotations import IDENTITY, quat_to_matrix, random_quaternions
from .spec import BodySpec, ShapeSpec

GRID_SHAPES = ("box", "sphere", "capsule", "hull")
HULL_POINTS = 16
"""Random points drawn per generated hull (its hull keeps most of them, always <= 64)."""


class GeneratorError(ValueError):
    """Parameters that pass type checks but cannot make a valid scene; the loader adds the entry."""


@dataclass
class Material:
    density: float | None = 1000.0  # [kg/m^3], used when mass is None
    mass: float | None = None  # [kg] per body, overrides density
    friction: float = 0.5
    restitution: float = 0.0
    name: str | None = None  # name prefix


def names(prefix: str | None, count: int) -> list:
    return [f"{prefix}_{i}" for i in range(count)] if prefix else [None] * count


def _make_bodies(shapes, positions, orientations, masses, inertias, material: Material) -> list[BodySpec]:
    labels = names(material.name, len(shapes))
    return [
        BodySpec(
            shapes=[shapes[i]],
            position=positions[i].copy(),
            orientation=orientations[i].copy(),
            linear_velocity=np.zeros(3),
            angular_velocity=np.zeros(3),
            mass=float(masses[i]),
            inertia=inertias[i].copy(),
            static=False,
            friction=material.friction,
            restitution=material.restitution,
            name=labels[i],
        )
        for i in range(len(shapes))
    ]


def _apply_mass(masses: np.ndarray, inertias: np.ndarray, material: Material):
    if material.mass is None:
        return masses, inertias
    scale = material.mass / masses
    return np.full_like(masses, material.mass), inertias * scale[:, None, None]


def box_bodies(positions, half_extents, orientations, material: Material) -> list[BodySpec]:
    """One box body per row: positions (N, 3), half_extents (N, 3), orientations (N, 4)."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    half_extents = np.asarray(half_extents, dtype=np.float64).reshape(-1, 3)
    orientations = np.asarray(orientations, dtype=np.float64).reshape(-1, 4)
    density = material.density if material.density is not None else 1.0
    masses, inertias = _apply_mass(*box_mass_properties_batch(half_extents, density), material)
    shapes = [ShapeSpec("box", half_extents=h.copy()) for h in half_extents]
    return _make_bodies(shapes, positions, orientations, masses, inertias, material)


def stack(count: int, half_extents, position, *, gap: float = 0.0, jitter: float = 0.0, seed: int | None = None,
          material: Material = Material()) -> list[BodySpec]:
    """``count`` equal boxes in a vertical column; ``position`` is the lowest box's centre.

    Box i sits at z = z0 + i (2 hz + gap). Random draws (only when jitter > 0): the
    x, y offsets of all boxes, uniform in [-jitter, jitter], shape (count, 2).
    """
    h = np.asarray(half_extents, dtype=np.float64)
    pos = np.tile(np.asarray(position, dtype=np.float64), (count, 1))
    pos[:, 2] += np.arange(count) * (2.0 * h[2] + gap)
    if jitter > 0:
        pos[:, :2] += np.random.default_rng(seed).uniform(-jitter, jitter, size=(count, 2))
    return box_bodies(pos, np.tile(h, (count, 1)), np.tile(IDENTITY, (count, 1)), material)


def pyramid_count(base: int, layout: str) -> int:
    return base * (base + 1) // 2 if layout == "2d" else base * (base + 1) * (2 * base + 1) // 6


def pyramid(base: int, half_extents, position, *, gap: float = 0.0, layout: str = "2d",
            material: Material = Material()) -> list[BodySpec]:
    """A pyramid of equal boxes; ``position`` is the centre of the base row (or base layer).

    ``2d``: one box deep (along y), row k has base - k boxes along x.
    ``3d``: layer k is a (base - k) x (base - k) square. Neighbours are 2 h + gap
    apart on every axis, so gap = 0 makes them touch exactly. Order: bottom row
    first, x fastest, then y.
    """
    h = np.asarray(half_extents, dtype=np.float64)
    step = 2.0 * h + gap
    rows = []
    for k in range(base):
        n = base - k
        offs = (np.arange(n) - (n - 1) / 2.0)
        if layout == "2d":
            xy = np.stack([offs * step[0], np.zeros(n)], axis=1)
        else:
            gx, gy = np.meshgrid(offs * step[0], offs * step[1], indexing="xy")
            xy = np.stack([gx.ravel(), gy.ravel()], axis=1)
        rows.append(np.column_stack([xy, np.full(len(xy), k * step[2])]))
    pos = np.concatenate(rows) + np.asarray(position, dtype=np.float64)
    return box_bodies(pos, np.tile(h, (len(pos), 1)), np.tile(IDENTITY, (len(pos), 1)), material)


def _grid_positions(counts, spacing, origin) -> np.ndarray:
    nx, ny, nz = (int(c) for c in counts)
    iz, iy, ix = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    idx = np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1)
    return np.asarray(origin, dtype=np.float64) + idx * np.asarray(spacing, dtype=np.float64)


def grid(counts, spacing, origin, *, shapes=("box",), weights=None, half_extents=None, half_extent_range=None,
         orientation="identity", seed: int | None = None, material: Material = Material()) -> list[BodySpec]:
    """Bodies on an nx x ny x nz lattice; ``origin`` is the centre of the body with the smallest x, y, z.

    Order: x fastest, then y, then z. Each body gets a half-size vector h (fixed
    ``half_extents``, or per-axis uniform in ``half_extent_range``) mapped to its
    shape: box half_extents = h; sphere radius = h_x; capsule radius = h_x / 2 and
    half_height = h_z / 2; hull = hull of HULL_POINTS points uniform in the box
    [-h, h], recentred on its centre of mass. ``orientation`` is "identity",
    "random" (uniform on SO(3)) or a (w, x, y, z) quaternion for every body.

    Random draws, in this order: shape kinds (only with more than one shape),
    half sizes (only with a range), orientations (only when random), hull points
    (one (HULL_POINTS, 3) draw per hull body, in body order).

    Raises GeneratorError when neighbouring bodies could overlap at t = 0 (the
    largest world-axis extent exceeds the spacing on some axis).
    """
    rng = np.random.default_rng(seed)
    pos = _grid_positions(counts, spacing, origin)
    n = len(pos)
    shapes = list(shapes)
    if len(shapes) > 1:
        p = None if weights is None else np.asarray(weights, dtype=np.float64) / float(np.sum(weights))
        kinds = np.asarray(shapes, dtype=object)[rng.choice(len(shapes), size=n, p=p)]
    else:
        kinds = np.full(n, shapes[0], dtype=object)
    if half_extent_range is not None:
        lo, hi = float(half_extent_range[0]), float(half_extent_range[1])
        halves = rng.uniform(lo, hi, size=(n, 3))
    else:
        halves = np.tile(np.asarray(half_extents, dtype=np.float64), (n, 1))
    if isinstance(orientation, str) and orientation == "random":
        quats = random_quaternions(rng, n)
    elif isinstance(orientation, str):
        quats = np.tile(IDENTITY, (n, 1))
    else:
        quats = np.tile(np.asarray(orientation, dtype=np.float64), (n, 1))
    rots = quat_to_matrix(quats)

    density = material.density if material.density is not None else 1.0
    masses = np.empty(n)
    inertias = np.empty((n, 3, 3))
    shape_specs: list[ShapeSpec | None] = [None] * n
    extent = np.empty((n, 3))  # world-axis half extent of each body, for the overlap check
    is_box = kinds == "box"
    if is_box.any():
        masses[is_box], inertias[is_box] = box_mass_properties_batch(halves[is_box], density)
        extent[is_box] = np.einsum("nij,nj->ni", np.abs(rots[is_box]), halves[is_box])
        for i in np.flatnonzero(is_box):
            shape_specs[i] = ShapeSpec("box", half_extents=halves[i].copy())
    for i in np.flatnonzero(~is_box):
        h = halves[i]
        if kinds[i] == "sphere":
            shape = ShapeSpec("sphere", radius=float(h[0]))
            mp = sphere_mass_properties(shape.radius, density)
            extent[i] = shape.radius
        elif kinds[i] == "capsule":
            shape = ShapeSpec("capsule", radius=float(h[0] / 2.0), half_height=float(h[2] / 2.0))
            mp = capsule_mass_properties(shape.radius, shape.half_height, density)
            extent[i] = shape.radius + np.abs(rots[i][:, 2]) * shape.half_height
        else:
            verts = hull_vertices(rng.uniform(-1.0, 1.0, size=(HULL_POINTS, 3)) * h)
            mp = hull_mass_properties(verts, density)
            verts = verts - mp.com
            shape = ShapeSpec("hull", vertices=verts)
            extent[i] = np.abs(verts @ rots[i].T).max(axis=0)
        shape_specs[i] = shape
        masses[i], inertias[i] = mp.mass, mp.inertia
    spacing = np.asarray(spacing, dtype=np.float64)
    counts = np.asarray(counts)
    for axis, label in enumerate("xyz"):
        widest = 2.0 * float(extent[:, axis].max())
        if counts[axis] > 1 and widest > spacing[axis] + 1e-9:
            raise GeneratorError(
                f"bodies may overlap at t=0: spacing along {label} is {spacing[axis]:g} m but the widest body "
                f"spans {widest:.4g} m along {label}; raise spacing or shrink the bodies"
            )
    masses, inertias = _apply_mass(masses, inertias, material)
    return _make_bodies(shape_specs, pos, quats, masses, inertias, material)
