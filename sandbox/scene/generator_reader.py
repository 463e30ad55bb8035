"""Readers of ``[[generate]]`` entries (stack, pyramid, grid, wall, rain) and of ``drop`` events,
which describe their bodies exactly like a ``rain`` generator. The expansion itself, seeded,
is ``generators.py``'s; this module checks the keys and the body budget.
"""

from __future__ import annotations

import math

import numpy as np

from . import generators
from .hull import HullError
from .keys import (DEFAULT_DENSITY, DEFAULT_FRICTION, DEFAULT_RESTITUTION, GENERATOR_KEYS, GENERATOR_KINDS,
                   GENERATOR_REQUIRED, MAX_BODIES)
from .schema import Reader
from .body_reader import read_resistances
from .spec import BodySpec


def _read_material(r: Reader) -> generators.Material:
    r.exclusive("density", "mass", required=False)
    name = r.string("name", None)
    if name is not None and not name:
        raise r.error("a name prefix must not be empty", "name")
    return generators.Material(
        density=r.real("density", DEFAULT_DENSITY, positive=True),
        mass=r.real("mass", None, positive=True),
        friction=r.real("friction", DEFAULT_FRICTION, nonnegative=True),
        restitution=r.real("restitution", DEFAULT_RESTITUTION, low=0.0, high=1.0),
        **read_resistances(r),
        name=name,
    )


def _read_box_size(r: Reader) -> np.ndarray:
    key = r.exclusive("half_extents", "size")
    v = r.scalar_or_vector(key, 3, positive=True)
    return v if key == "half_extents" else v / 2.0


def _need_seed(r: Reader, why: str) -> int:
    if not r.has("seed"):
        raise r.error(f"missing required key 'seed' ({why} draws random numbers)", "seed")
    return r.integer("seed", minimum=0)


def _check_budget(r: Reader, key: str, count: int, budget: int) -> None:
    if count > budget:
        raise r.error(f"would generate {count} bodies; a scene holds at most {MAX_BODIES}", key)


def read_generator(r: Reader, *, budget: int) -> list[BodySpec]:
    kind = r.string("kind", choices=GENERATOR_KINDS, what="generator kind")
    r.check_keys(GENERATOR_KEYS[kind], required=("kind",) + GENERATOR_REQUIRED[kind], what=f"a '{kind}' generator")
    return _expanded(r, kind, budget)


def _expanded(r: Reader, kind: str, budget: int) -> list[BodySpec]:
    """The bodies of a generator entry (or of a drop event, kind 'rain') whose keys are checked."""
    material = _read_material(r)
    try:
        with np.errstate(all="ignore"):
            bodies = _expand(r, kind, material, budget)
    except generators.GeneratorError as exc:
        raise r.error(str(exc), exc.key) from None
    except HullError as exc:
        raise r.error(f"a generated hull is invalid: {exc}") from None
    for body in bodies:
        if not (np.all(np.isfinite(body.position)) and math.isfinite(body.mass) and body.mass > 0
                and np.all(np.isfinite(body.inertia))):
            raise r.error("generated positions or mass properties are not finite and positive; check sizes, "
                          "spacing and density")
    return bodies


def _expand(r: Reader, kind: str, material: generators.Material, budget: int) -> list[BodySpec]:
    if kind == "stack":
        count = r.integer("count", minimum=1)
        _check_budget(r, "count", count, budget)
        half = _read_box_size(r)
        jitter = r.real("jitter", 0.0, nonnegative=True)
        seed = _need_seed(r, "jitter > 0") if jitter > 0 else r.integer("seed", None, minimum=0)
        return generators.stack(count, half, r.vector("position", 3), gap=r.real("gap", 0.0, nonnegative=True),
                                jitter=jitter, seed=seed, material=material)
    if kind == "wall":
        rows = r.integer("rows", minimum=1)
        columns = r.integer("columns", minimum=1)
        _check_budget(r, "rows", min(rows, 10**7) * min(columns, 10**7), budget)
        return generators.wall(rows, columns, _read_box_size(r), r.vector("position", 3),
                               direction=r.string("direction", "x", choices=generators.WALL_DIRECTIONS,
                                                  what="wall direction"),
                               bond=r.string("bond", "stack", choices=generators.WALL_BONDS, what="wall bond"),
                               gap=r.real("gap", 0.0, nonnegative=True), material=material)
    if kind == "rain":
        return _read_rain(r, material, budget)
    if kind == "pyramid":
        base = r.integer("base", minimum=1)
        layout = r.string("layout", "2d", choices=("2d", "3d"), what="pyramid layout")
        _check_budget(r, "base", generators.pyramid_count(min(base, 10**7), layout), budget)
        return generators.pyramid(base, _read_box_size(r), r.vector("position", 3),
                                  gap=r.real("gap", 0.0, nonnegative=True), layout=layout, material=material)
    # grid
    counts = r.int_vector("counts", 3, minimum=1)
    _check_budget(r, "counts", int(np.prod([min(int(c), 10**7) for c in counts])), budget)
    spacing = r.scalar_or_vector("spacing", 3, positive=True)
    origin = r.vector("origin", 3)
    shapes, weights, half_extents, half_range, orientation = _read_shape_mix(r, "identity", "grid")
    random_reasons = [why for why, used in (("more than one shape", len(shapes) > 1),
                                            ("half_extent_range", half_range is not None),
                                            ("orientation = 'random'", isinstance(orientation, str) and orientation == "random"),
                                            ("a hull shape", "hull" in shapes)) if used]
    seed = _need_seed(r, random_reasons[0]) if random_reasons else r.integer("seed", None, minimum=0)
    return generators.grid(counts, spacing, origin, shapes=shapes, weights=weights, half_extents=half_extents,
                           half_extent_range=half_range, orientation=orientation, seed=seed, material=material)


def _read_rain(r: Reader, material: generators.Material, budget: int) -> list[BodySpec]:
    count = r.integer("count", minimum=1)
    _check_budget(r, "count", count, budget)
    region = r.points("region")
    if len(region) != 2:
        raise r.error(f"expected [[x0, y0, z0], [x1, y1, z1]] (two corners), got {len(region)} points", "region")
    low, high = region
    if not np.all(low < high):
        raise r.error(f"region corners must satisfy low < high on every axis, got low {low.tolist()} and high "
                      f"{high.tolist()}", "region")
    shapes, weights, half_extents, half_range, orientation = _read_shape_mix(r, "random", "rain")
    linear_velocity = r.vector("linear_velocity", 3, (0.0, 0.0, 0.0))
    angular_velocity = r.vector("angular_velocity", 3, (0.0, 0.0, 0.0))
    return generators.rain(count, low, high, shapes=shapes, weights=weights, half_extents=half_extents,
                           half_extent_range=half_range, orientation=orientation,
                           seed=r.integer("seed", minimum=0), linear_velocity=linear_velocity,
                           angular_velocity=angular_velocity, material=material)


def _read_shape_mix(r: Reader, default_orientation: str, label: str):
    """shapes, weights, half_extents or half_extent_range, orientation: the keys grid and rain share."""
    shapes = r.choice_list("shapes", generators.GRID_SHAPES, what=f"{label} shape") if r.has("shapes") else ["box"]
    weights = None
    if r.has("weights"):
        if len(shapes) < 2:
            raise r.error("weights need at least two entries in 'shapes'", "weights")
        weights = r.vector("weights", len(shapes), nonnegative=True)
        if not weights.sum() > 0:
            raise r.error("weights must not all be zero", "weights")
    size_key = r.exclusive("half_extents", "half_extent_range")
    half_extents = half_range = None
    if size_key == "half_extents":
        half_extents = r.scalar_or_vector("half_extents", 3, positive=True)
    else:
        half_range = r.vector("half_extent_range", 2, positive=True)
        if half_range[0] > half_range[1]:
            raise r.error(f"expected [low, high] with low <= high, got {half_range.tolist()}", "half_extent_range")
    orientation = default_orientation
    if r.has("orientation"):
        if isinstance(r.data["orientation"], str):
            orientation = r.string("orientation", choices=("identity", "random"), what=f"{label} orientation")
        else:
            orientation = r.quaternion("orientation")
    return shapes, weights, half_extents, half_range, orientation



def read_drop(r: Reader, budget: int) -> list[BodySpec]:
    """The bodies of a ``drop`` event, whose keys the timeline has checked: a ``rain`` expansion."""
    return _expanded(r, "rain", budget)
