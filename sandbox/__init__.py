"""Mass-splitting rigid-body sandbox: Tonge et al. 2012 beside PGS and projected Jacobi,
all in Taichi kernels.

    from sandbox import Scene, World
    world = World(Scene.load("scenes/pyramid_20.toml"), solver="mass-splitting", iterations=15, arch="cpu")
    world.step(600)
    world.state()["position"]

These are the package's public names, the only ones ``web/`` uses (tests/test_import_graph.py
checks it). The engine's names (``World``, ``SOLVERS``, ``Recorder``, the backend's) are
imported on first use, so loading scenes (``sandbox.scene``) neither starts Taichi nor pulls in
the engine (tests/scene/test_loader.py checks it).
"""

import importlib

from .errors import CapacityError, SandboxError, SceneError, SimulationError
from .scene import (EFFECTS, IDENTITY, BodySpec, EventSpec, GeneratorError, Material, Scene, ShapeSpec, quat_to_matrix,
                    rain, resolve_scene, shipped_scenes)
from .settings import FORMULATIONS, Settings

__all__ = [
    # simulation
    "Scene", "World", "Settings", "SOLVERS", "FORMULATIONS", "Recorder",
    # errors
    "SandboxError", "SceneError", "SimulationError", "CapacityError",
    # the Taichi backend
    "init_backend", "resolve_arch",
    # scenes: the shipped library, the pieces a scene (or an edit of a running world) is made of
    "resolve_scene", "shipped_scenes", "BodySpec", "ShapeSpec", "EventSpec", "EFFECTS",
    "rain", "Material", "GeneratorError",
    # host-side rotations
    "IDENTITY", "quat_to_matrix",
]


# public name -> (module, attribute), imported on first use
_ENGINE_NAMES = {
    "World": (".world", "World"),
    "SOLVERS": (".solvers", "SOLVERS"),
    "Recorder": (".recording", "Recorder"),
    "init_backend": (".backend", "init"),
    "resolve_arch": (".backend", "resolve_arch"),
}


def __getattr__(name):
    if name in _ENGINE_NAMES:
        module, attribute = _ENGINE_NAMES[name]
        return getattr(importlib.import_module(module, __name__), attribute)
    raise AttributeError(f"module 'sandbox' has no attribute {name!r}")
