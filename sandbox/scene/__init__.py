"""Scenes: the TOML/dict schema, its validation, generators and mass properties.

Pure Python + numpy (+ scipy/trimesh only when a scene has hulls or mesh files);
nothing here imports Taichi, so scenes load, validate and expand without a runtime.
"""

from .loader import EFFECTS, EVENT_KINDS, GENERATOR_KINDS, MAX_BODIES, SOLVER_NAMES, load_scene, scene_from_dict
from .massprops import MassProperties, body_mass_properties
from .spec import BodySpec, EventSpec, MeshSpec, PlaneSpec, Scene, ShapeSpec, SolverSpec, WorldSpec

__all__ = [
    "Scene",
    "BodySpec",
    "ShapeSpec",
    "PlaneSpec",
    "MeshSpec",
    "WorldSpec",
    "EventSpec",
    "SolverSpec",
    "load_scene",
    "scene_from_dict",
    "SOLVER_NAMES",
    "GENERATOR_KINDS",
    "EVENT_KINDS",
    "EFFECTS",
    "MAX_BODIES",
    "MassProperties",
    "body_mass_properties",
]
