"""Readers of ``[[body]]`` entries and convex ``[[static]]`` entries: shapes, compounds, mass
properties and the centre-of-mass shift (see ``loader.py``), breakability.
"""

from __future__ import annotations

import math

import numpy as np

from .hull import HullError, hull_vertices, reduce_to_hull
from .keys import (BODY_KEYS, BODY_SHAPES, DEFAULT_DENSITY, DEFAULT_FRICTION, DEFAULT_RESTITUTION, PART_KEYS,
                   PART_SHAPES, SHAPE_KEYS, SHAPE_REQUIRED, SOLID_SHAPES, STATIC_SOLID_KEYS)
from .massprops import combine, part_mass_properties
from .mesh_reader import load_mesh_file, read_mesh_body
from .rotations import quat_to_matrix
from .schema import Reader
from .spec import DEFAULT_PIECES, MAX_PIECES, RESISTANCE_KEYS, BodySpec, ShapeSpec


def _read_shape(r: Reader, kind: str) -> ShapeSpec:
    """One convex shape in its own frame (the caller sets the local pose)."""
    if kind == "box":
        return ShapeSpec("box", half_extents=r.vector("half_extents", 3, positive=True))
    if kind == "sphere":
        return ShapeSpec("sphere", radius=r.real("radius", positive=True))
    if kind == "capsule":
        return ShapeSpec("capsule", radius=r.real("radius", positive=True),
                         half_height=r.real("half_height", positive=True))
    # hull
    source = r.exclusive("vertices", "path")
    scale = r.scalar_or_vector("scale", 3, 1.0, positive=True)
    with np.errstate(all="ignore"):
        try:
            if source == "vertices":
                points = r.points("vertices") * scale
                if not np.all(np.isfinite(points)):
                    raise HullError("scaled hull vertices overflow")
                vertices = hull_vertices(points)
            else:
                mesh_vertices, _ = load_mesh_file(r, "path")
                vertices = reduce_to_hull(mesh_vertices * scale)
        except HullError as exc:
            raise r.error(str(exc), source) from None
    return ShapeSpec("hull", vertices=vertices)


def read_solid(r: Reader, *, static_section: bool) -> BodySpec:
    """A ``[[body]]`` entry, or a convex ``[[static]]`` entry (box/sphere/capsule/hull/compound)."""
    kind = r.string("shape", choices=SOLID_SHAPES if static_section else BODY_SHAPES, what="shape")
    base = STATIC_SOLID_KEYS if static_section else BODY_KEYS
    r.check_keys(base + SHAPE_KEYS[kind], required=("position",) + SHAPE_REQUIRED[kind],
                 what=f"a {'static ' if static_section else ''}{kind}")
    decomposition = None
    if kind == "compound":
        parts = r.tables("parts")
        if not parts:
            raise r.error("a compound needs at least one part", "parts")
        shapes, densities = [], []
        for p in parts:
            pk = p.string("shape", choices=PART_SHAPES, what="compound part shape")
            p.check_keys(PART_KEYS + SHAPE_KEYS[pk], required=SHAPE_REQUIRED[pk], what=f"a {pk} part")
            shape = _read_shape(p, pk)
            shape.local_position = p.vector("position", 3, (0.0, 0.0, 0.0))
            shape.local_orientation = p.quaternion("orientation")
            shapes.append(shape)
            densities.append(p.real("density", None, positive=True))
    elif kind == "mesh":
        shapes, decomposition = read_mesh_body(r)
        densities = [None] * len(shapes)
    else:
        shapes, densities = [_read_shape(r, kind)], [None]
    position = r.vector("position", 3)
    orientation = r.quaternion("orientation")
    static = static_section or r.boolean("static", False)
    r.exclusive("density", "mass", required=False)
    density = r.real("density", DEFAULT_DENSITY, positive=True)  # a static section rejected the key already
    mass = r.real("mass", None, positive=True)
    linear_velocity = r.vector("linear_velocity", 3, (0.0, 0.0, 0.0))
    angular_velocity = r.vector("angular_velocity", 3, (0.0, 0.0, 0.0))
    if static and (np.any(linear_velocity) or np.any(angular_velocity)):
        key = "linear_velocity" if np.any(linear_velocity) else "angular_velocity"
        raise r.error("a static body cannot move; remove the velocity or set static = false", key)
    with np.errstate(all="ignore"):
        if decomposition is not None:
            parts = decomposition.parts(mass if mass is not None else density * decomposition.mesh_volume)
        else:
            parts = part_mass_properties(shapes, [d if d is not None else density for d in densities])
        mp = parts[0] if len(parts) == 1 else combine(parts)
        if not (math.isfinite(mp.mass) and mp.mass > 0 and np.all(np.isfinite(mp.inertia))):
            raise r.error(f"mass properties are not finite and positive (mass {mp.mass:g} kg); check sizes and density")
        if mass is not None and decomposition is None:
            factor = mass / mp.mass
            mp, parts = mp.scaled(factor), [p.scaled(factor) for p in parts]
        for shape, part in zip(shapes, parts):
            shape.local_position = shape.local_position - mp.com
            if len(shapes) >= 2:  # each shape's share, for a fracture into the shapes (fracture.py)
                shape.piece_mass, shape.piece_com, shape.piece_inertia = part.mass, part.com - mp.com, part.inertia
        com_world = position + quat_to_matrix(orientation) @ mp.com
        if not (np.all(np.isfinite(com_world)) and np.all(np.isfinite(mp.inertia)) and math.isfinite(mp.mass)):
            raise r.error("position or mass properties overflow to inf")
    name = r.string("name", None)
    if name is not None and not name:
        raise r.error("a name must not be empty", "name")
    breakable, strength, pieces = _read_breakable(r, static)
    return BodySpec(
        shapes=shapes,
        position=com_world,
        orientation=orientation,
        linear_velocity=linear_velocity,
        angular_velocity=angular_velocity,
        mass=float(mp.mass),
        inertia=mp.inertia,
        static=static,
        friction=r.real("friction", DEFAULT_FRICTION, nonnegative=True),
        restitution=r.real("restitution", DEFAULT_RESTITUTION, low=0.0, high=1.0),
        **read_resistances(r),
        name=name,
        breakable=breakable,
        strength=strength,
        pieces=pieces,
    )


def read_resistances(r: Reader) -> dict[str, float]:
    """The motion resistances (spec.RESISTANCE_KEYS) the entry gives, each >= 0, default 0;
    the entry's key check has already refused those its table does not take."""
    return {key: r.real(key, 0.0, nonnegative=True) for key in RESISTANCE_KEYS}


def _read_breakable(r: Reader, static: bool) -> tuple[bool, float | None, int]:
    """``breakable``, ``strength`` [N s] (required with it) and ``pieces`` (only with it)."""
    breakable = r.boolean("breakable", False)
    if not breakable:
        for key in ("strength", "pieces"):
            if r.has(key):
                raise r.error(f"'{key}' applies only to breakable bodies (set breakable = true)", key)
        return False, None, DEFAULT_PIECES
    if static:
        raise r.error("a static body cannot be breakable", "breakable")
    if not r.has("strength"):
        raise r.error("a breakable body needs 'strength' [N s]: the normal impulse one contact may pass to it in "
                      "one step before it breaks", "strength")
    return True, r.real("strength", positive=True), r.integer("pieces", DEFAULT_PIECES, minimum=2, maximum=MAX_PIECES)

