"""Scene generators: stacks, pyramids, grids, brick walls and rain, expanded into BodySpecs.

Each generator is deterministic: random draws come from one
``numpy.random.default_rng(seed)`` per ``[[generate]]`` entry, in a fixed order
(stated per generator), so a seed reproduces a scene exactly on any machine with
the same numpy. Positions and mass properties are computed for all bodies at
once (boxes analytically in one batch), so a 1000-body pile expands in a few
milliseconds; only then is one ``BodySpec`` made per body.

Generated bodies start at rest (``rain`` alone takes an optional common initial
velocity, which timeline ``drop`` events use to fire projectiles). Names, when a
``name`` prefix is given, are ``<prefix>_<i>`` with i counting from 0 in
generation order.
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
from .spec import RESISTANCE_KEYS, BodySpec, ShapeSpec

GRID_SHAPES = ("box", "sphere", "capsule", "hull")
WALL_DIRECTIONS = ("x", "y")
WALL_BONDS = ("stack", "running")
RAIN_MAX_CELLS_PER_AXIS = 1 << 20
"""A rain region is cut into at most this many cells per axis (so the cell count fits an int64)."""
HULL_POINTS = 16
"""Random points drawn per generated hull (its hull keeps most of them, always <= 64)."""


class GeneratorError(ValueError):
    """Parameters that pass type checks but cannot make a valid scene; the loader adds the entry
    (and ``key``, the offending key, when there is one)."""

    def __init__(self, problem: str, key: str | None = None):
        super().__init__(problem)
        self.key = key


@dataclass
class Material:
    density: float | None = 1000.0  # [kg/m^3], used when mass is None
    mass: float | None = None  # [kg] per body, overrides density
    friction: float = 0.5
    restitution: float = 0.0
    linear_damping: float = 0.0  # [1/s] (spec.RESISTANCE_KEYS)
    angular_damping: float = 0.0  # [1/s]
    rolling_friction: float = 0.0  # [m]
    torsional_friction: float = 0.0  # [m]
    name: str | None = None  # name prefix


def names(prefix: str | None, count: int) -> list:
    return [f"{prefix}_{i}" for i in range(count)] if prefix else [None] * count


def _make_bodies(shapes, positions, orientations, masses, inertias, material: Material, *,
                 linear_velocity=None, angular_velocity=None) -> list[BodySpec]:
    labels = names(material.name, len(shapes))
    v = np.zeros(3) if linear_velocity is None else np.asarray(linear_velocity, dtype=np.float64)
    w = np.zeros(3) if angular_velocity is None else np.asarray(angular_velocity, dtype=np.float64)
    return [
        BodySpec(
            shapes=[shapes[i]],
            position=positions[i].copy(),
            orientation=orientations[i].copy(),
            linear_velocity=v.copy(),
            angular_velocity=w.copy(),
            mass=float(masses[i]),
            inertia=inertias[i].copy(),
            static=False,
            friction=material.friction,
            restitution=material.restitution,
            **{key: getattr(material, key) for key in RESISTANCE_KEYS},
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


def _draw_kinds_sizes_orientations(rng, n: int, shapes, weights, half_extents, half_extent_range, orientation):
    """Shape kinds (only with several shapes), half-size vectors (only with a range) and
    orientations (only when random) of ``n`` bodies, drawn from ``rng`` in that order."""
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
    return kinds, halves, quats


def _shape_batch(kinds, halves, rots, rng, density: float):
    """Shapes, masses (N,), inertias (N, 3, 3) and world-axis half extents (N, 3) of the bodies.

    Half-size vector h per shape: box half_extents = h; sphere radius = h_x; capsule
    radius = h_x / 2, half_height = h_z / 2; hull = hull of HULL_POINTS points uniform
    in [-h, h] (one draw from ``rng`` per hull, in body order), recentred on its centre
    of mass. Boxes are done in one batch; the other kinds one by one.
    """
    n = len(kinds)
    masses = np.empty(n)
    inertias = np.empty((n, 3, 3))
    shape_specs: list[ShapeSpec | None] = [None] * n
    extent = np.empty((n, 3))  # world-axis half extent of each body about its centre of mass
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
    return shape_specs, masses, inertias, extent


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
    kinds, halves, quats = _draw_kinds_sizes_orientations(rng, n, shapes, weights, half_extents, half_extent_range,
                                                          orientation)
    rots = quat_to_matrix(quats)
    density = material.density if material.density is not None else 1.0
    shape_specs, masses, inertias, extent = _shape_batch(kinds, halves, rots, rng, density)
    spacing = np.asarray(spacing, dtype=np.float64)
    counts = np.asarray(counts)
    for axis, label in enumerate("xyz"):
        widest = 2.0 * float(extent[:, axis].max())
        if counts[axis] > 1 and widest > spacing[axis] + 1e-9:
            raise GeneratorError(
                f"bodies may overlap at t=0: spacing along {label} is {spacing[axis]:g} m but the widest body "
                f"spans {widest:.4g} m along {label}; raise spacing or shrink the bodies",
                key="spacing",
            )
    masses, inertias = _apply_mass(masses, inertias, material)
    return _make_bodies(shape_specs, pos, quats, masses, inertias, material)


def wall_count(rows: int, columns: int) -> int:
    return rows * columns


def wall(rows: int, columns: int, half_extents, position, *, direction: str = "x", bond: str = "stack",
         gap: float = 0.0, material: Material = Material()) -> list[BodySpec]:
    """A brick wall of ``rows`` x ``columns`` equal boxes, identity orientations.

    ``half_extents`` is one brick in the wall's frame: [along the wall, across it
    (thickness), vertical]; for ``direction`` "y" the box's x and y half extents are
    swapped so the wall runs along y. Neighbours are 2 h + gap apart along the wall
    and vertically (gap = 0: touching). ``position`` is the centre of the bottom row
    (its z is the bottom bricks' centre height). ``bond`` "running" shifts every odd
    row (1, 3, ...) by half a brick pitch towards +direction (a running bond, each
    brick resting on two below); "stack" keeps the columns aligned. Order: bottom
    row first, along the wall fastest. No random draws.
    """
    h = np.asarray(half_extents, dtype=np.float64)
    pitch = 2.0 * h[0] + gap
    rise = 2.0 * h[2] + gap
    row, col = np.divmod(np.arange(rows * columns), columns)
    along = (col - (columns - 1) / 2.0) * pitch
    if bond == "running":
        along = along + (row % 2) * (pitch / 2.0)
    offsets = np.zeros((len(row), 3))
    axis = 0 if direction == "x" else 1
    offsets[:, axis] = along
    offsets[:, 2] = row * rise
    world_half = h if direction == "x" else h[[1, 0, 2]]
    pos = np.asarray(position, dtype=np.float64) + offsets
    n = len(pos)
    return box_bodies(pos, np.tile(world_half, (n, 1)), np.tile(IDENTITY, (n, 1)), material)


def rain(count: int, low, high, *, shapes=("box",), weights=None, half_extents=None, half_extent_range=None,
         orientation="random", seed: int | None = None, linear_velocity=None, angular_velocity=None,
         material: Material = Material()) -> list[BodySpec]:
    """``count`` random bodies inside the axis-aligned box [low, high], not touching each other.

    Shapes, half-size vectors and orientations are drawn exactly as ``grid`` draws
    them (kinds with several shapes, sizes with a range, orientations when random,
    one point draw per hull). The region is then cut into a lattice of equal cells,
    each at least as wide on every axis as the widest body's world-axis extent
    (as many cells per axis as fit, at most RAIN_MAX_CELLS_PER_AXIS); ``count``
    distinct cells are chosen uniformly (``rng.choice(cells, count, replace=False)``,
    sorted, so body order is bottom-up, x fastest), and each body is jittered
    uniformly inside its own cell by the room its extent leaves (one (count, 3)
    uniform draw). Every body therefore lies inside the region and inside its own
    cell: no two overlap at t = 0. All bodies get the same initial velocities.

    Raises GeneratorError when the region holds fewer cells than ``count``.
    """
    rng = np.random.default_rng(seed)
    low = np.asarray(low, dtype=np.float64)
    high = np.asarray(high, dtype=np.float64)
    kinds, halves, quats = _draw_kinds_sizes_orientations(rng, count, shapes, weights, half_extents,
                                                          half_extent_range, orientation)
    rots = quat_to_matrix(quats)
    density = material.density if material.density is not None else 1.0
    shape_specs, masses, inertias, extent = _shape_batch(kinds, halves, rots, rng, density)
    span = high - low
    need = 2.0 * extent.max(axis=0)  # [m] the smallest cell that holds the widest body, per axis
    with np.errstate(all="ignore"):
        fit = np.minimum(np.floor(span / need), RAIN_MAX_CELLS_PER_AXIS)
    cells = np.where(np.isfinite(fit), fit, 0).astype(np.int64)
    capacity = int(np.prod(cells))
    if capacity < count:
        widest = ", ".join(f"{x:.4g}" for x in need)
        room = " x ".join(str(int(c)) for c in cells)
        raise GeneratorError(
            f"region too small: {count} bodies need {count} separate cells, but a region of "
            f"{' x '.join(f'{x:.4g}' for x in span)} m holds only {room} = {capacity} cells of the widest "
            f"body's extent ({widest} m); enlarge the region, shrink the bodies or lower count",
            key="region",
        )
    chosen = np.sort(rng.choice(capacity, size=count, replace=False))
    iz, rest = np.divmod(chosen, cells[0] * cells[1])
    iy, ix = np.divmod(rest, cells[0])
    size = span / cells
    centre = low + (np.stack([ix, iy, iz], axis=1) + 0.5) * size
    slack = np.maximum(size / 2.0 - extent, 0.0)
    pos = centre + rng.uniform(-1.0, 1.0, size=(count, 3)) * slack
    masses, inertias = _apply_mass(masses, inertias, material)
    return _make_bodies(shape_specs, pos, quats, masses, inertias, material,
                        linear_velocity=linear_velocity, angular_velocity=angular_velocity)
