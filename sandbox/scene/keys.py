"""The scene schema as data: which keys each table takes, which it needs, the defaults and limits.

The readers (``world_reader``, ``body_reader``, ``mesh_reader``, ``generator_reader``) check
every table against these tuples, so a key is added or renamed here once; the user-facing
description of every key is ``scenes/README.md``.
"""

from __future__ import annotations

from . import timeline
from .spec import RESISTANCE_KEYS
from ..solvers import MAX_SEED, SOLVERS  # the registry itself (Taichi-free), so names and options cannot drift

SOLVER_NAMES = tuple(SOLVERS)
SOLVER_OPTIONS = {name: tuple(info.defaults) for name, info in SOLVERS.items()}
"""Options each solver takes, from the solver registry, so a misplaced option fails at load time
with its entry, not later in ``World``."""
GENERATOR_KINDS = ("stack", "pyramid", "grid", "wall", "rain")
EVENT_KINDS = timeline.EVENT_KINDS
EFFECTS = ("friction", "restitution", "sleeping")
"""Optional effects a scene may call for (``effects = [...]``); the engine compiles the others away.
``sleeping``: resting islands stop being simulated until something touches them (sleep.py)."""
DEFAULT_EFFECTS = ("friction", "restitution")
"""The effects of a scene without an ``effects`` line: sleeping is asked for, never assumed (it
must not hide a solver's jitter in a comparison)."""
PART_SHAPES = ("box", "sphere", "capsule", "hull")
SOLID_SHAPES = PART_SHAPES + ("compound",)
BODY_SHAPES = SOLID_SHAPES + ("mesh",)
"""A ``[[body]]`` may be a decomposed mesh; in ``[[static]]``, ``mesh`` is a static triangle mesh."""
STATIC_SHAPES = ("plane", "mesh") + SOLID_SHAPES

DEFAULT_DENSITY = 1000.0  # [kg/m^3]
DEFAULT_FRICTION = 0.5
DEFAULT_RESTITUTION = 0.0
MAX_BODIES = 1_000_000
"""Sanity limit on the bodies of one scene (catches a typo such as count = 1e9 before memory runs out)."""
MAX_ITERATIONS = timeline.MAX_ITERATIONS
MAX_HEIGHTFIELD_CELLS = 2048
"""Per axis; 2048 x 2048 cells is 8.4 million triangles."""

TOP_KEYS = ("description", "world", "solver", "static", "body", "generate", "event", "effects")
WORLD_KEYS = ("gravity", "dt", "substeps", "contact_hertz", "duration", "speculative_contacts", "speculative_speed",
              "formulation", "baumgarte")
SOLVER_OPTION_KEYS = ("shuffle", "relaxation", "seed")
SOLVER_KEYS = ("name", "iterations") + SOLVER_OPTION_KEYS
SHAPE_KEYS = {
    "box": ("half_extents",),
    "sphere": ("radius",),
    "capsule": ("radius", "half_height"),
    "hull": ("vertices", "path", "scale"),
    "compound": ("parts",),
    "mesh": ("path", "generator", "scale", "decomposition"),
}
SHAPE_REQUIRED = {"box": ("half_extents",), "sphere": ("radius",), "capsule": ("radius", "half_height"),
                  "hull": (), "compound": ("parts",), "mesh": ()}
BODY_KEYS = ("shape", "position", "orientation", "linear_velocity", "angular_velocity", "density", "mass",
             "friction", "restitution", "name", "static", "breakable", "strength", "pieces") + RESISTANCE_KEYS
DECOMPOSITION_KEYS = ("threshold", "max_hulls", "seed", "max_hull_vertices", "timeout", "on_failure")
STATIC_SOLID_KEYS = ("shape", "position", "orientation", "friction", "restitution", "name", "rolling_friction",
                     "torsional_friction")
PART_KEYS = ("shape", "position", "orientation", "density")
PLANE_KEYS = ("shape", "normal", "offset", "friction", "restitution")
MESH_KEYS = ("shape", "path", "heightfield", "position", "orientation", "scale", "friction", "restitution", "name")
HEIGHTFIELD_KEYS = {
    "sines": ("function", "amplitude", "frequency", "size", "cells"),
    "noise": ("function", "amplitude", "size", "cells", "seed", "smoothing"),
}
HEIGHTFIELD_REQUIRED = {"sines": ("amplitude", "size", "cells"), "noise": ("amplitude", "size", "cells", "seed")}
MATERIAL_KEYS = ("density", "mass", "friction", "restitution", "name") + RESISTANCE_KEYS
RAIN_KEYS = ("count", "region", "shapes", "weights", "half_extents", "half_extent_range", "orientation", "seed",
             "linear_velocity", "angular_velocity") + MATERIAL_KEYS
GENERATOR_KEYS = {
    "stack": ("kind", "count", "half_extents", "size", "position", "gap", "jitter", "seed") + MATERIAL_KEYS,
    "pyramid": ("kind", "base", "half_extents", "size", "position", "gap", "layout") + MATERIAL_KEYS,
    "grid": ("kind", "counts", "spacing", "origin", "shapes", "weights", "half_extents", "half_extent_range",
             "orientation", "seed") + MATERIAL_KEYS,
    "wall": ("kind", "rows", "columns", "half_extents", "size", "position", "direction", "bond", "gap")
    + MATERIAL_KEYS,
    "rain": ("kind",) + RAIN_KEYS,
}
GENERATOR_REQUIRED = {"stack": ("count", "position"), "pyramid": ("base", "position"),
                      "grid": ("counts", "spacing", "origin"), "wall": ("rows", "columns", "position"),
                      "rain": ("count", "region", "seed")}
EVENT_KEYS = {  # kind -> (allowed keys, required keys)
    "drop": (("time", "kind") + RAIN_KEYS, ("time", "kind", "count", "region", "seed")),
    "set_velocity": (("time", "kind", "bodies", "linear_velocity", "angular_velocity"), ("time", "kind", "bodies")),
    "impulse": (("time", "kind", "bodies", "impulse", "point"), ("time", "kind", "bodies", "impulse")),
    "remove": (("time", "kind", "bodies"), ("time", "kind", "bodies")),
    "solver": (("time", "kind", "name", "iterations") + SOLVER_OPTION_KEYS, ("time", "kind", "name")),
    "iterations": (("time", "kind", "iterations"), ("time", "kind", "iterations")),
    "gravity": (("time", "kind", "gravity"), ("time", "kind", "gravity")),
    "effects": (("time", "kind", "effects"), ("time", "kind", "effects")),
    "fracture": (("time", "kind", "bodies", "pieces", "seed", "impulse"), ("time", "kind", "bodies")),
    "formulation": (("time", "kind", "formulation", "baumgarte"), ("time", "kind", "formulation")),
}

