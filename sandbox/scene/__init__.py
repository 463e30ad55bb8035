"""Scenes: the TOML/dict schema, its validation, generators and mass properties."""

from .spec import BodySpec, MeshSpec, PlaneSpec, Scene, ShapeSpec, SolverSpec, WorldSpec

__all__ = ["Scene", "BodySpec", "ShapeSpec", "PlaneSpec", "MeshSpec", "WorldSpec", "SolverSpec"]
