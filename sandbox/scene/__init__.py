"""Scenes: the TOML/dict schema, its validation, generators and mass properties.

Pure Python + numpy (+ scipy/trimesh only when a scene has hulls or mesh files);
nothing here imports Taichi, so scenes load, validate and expand without a runtime.

Import direction inside the package (no file imports one that imports it): ``spec`` (the
dataclasses) and ``schema`` (the table reader) at the bottom; the section readers and
``timeline`` above them; ``loader`` (the entry points) on top; this file wires the entry
points onto ``Scene`` as ``Scene.load`` and ``Scene.from_dict``.
"""

from .generators import GeneratorError, Material, rain
from .keys import EFFECTS, EVENT_KINDS, GENERATOR_KINDS, MAX_BODIES, SOLVER_NAMES
from .library import resolve_scene, shipped_scenes
from .loader import load_scene, scene_from_dict
from .massprops import MassProperties, body_mass_properties
from .rotations import IDENTITY, quat_to_matrix
from .spec import BodySpec, EventSpec, MeshSpec, PlaneSpec, Scene, ShapeSpec, SolverSpec, WorldSpec


def _load(cls, path) -> Scene:
    """Load and validate a TOML scene file (``load_scene``); errors name the file and entry."""
    return load_scene(path)


def _from_dict(cls, data: dict, *, source: str = "<dict>", base_dir=None) -> Scene:
    """Validate and expand a scene given as a dict with the TOML file's structure (``scene_from_dict``)."""
    return scene_from_dict(data, source=source, base_dir=base_dir)


for _name, _method in (("load", _load), ("from_dict", _from_dict)):
    _method.__name__, _method.__qualname__ = _name, f"Scene.{_name}"
    setattr(Scene, _name, classmethod(_method))

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
    "resolve_scene",
    "shipped_scenes",
    "SOLVER_NAMES",
    "GENERATOR_KINDS",
    "EVENT_KINDS",
    "EFFECTS",
    "MAX_BODIES",
    "MassProperties",
    "body_mass_properties",
    "quat_to_matrix",
    "IDENTITY",
    "rain",
    "Material",
    "GeneratorError",
]
