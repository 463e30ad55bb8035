"""Mass-splitting rigid-body sandbox: Tonge et al. 2012 beside PGS and projected Jacobi,
all in Taichi kernels.

    from sandbox import Scene, World
    world = World(Scene.load("scenes/pyramid_20.toml"), solver="mass-splitting", iterations=15, arch="cpu")
    world.step(600)
    world.state()["position"]

These are the package's public names, the only ones ``web/`` uses (tests/test_import_graph.py
checks it). ``World`` and ``SOLVERS`` are imported on first use, so the scene layer
(``sandbox.scene``) stays usable without starting Taichi; everything else here is pure Python
and numpy.
"""

from .backend import init as init_backend
from .backend import resolve_arch
from .errors import CapacityError, SandboxError, SceneError, SimulationError
from .recording import Recorder
from .scene import (EFFECTS, IDENTITY, BodySpec, EventSpec, GeneratorError, Material, Scene, ShapeSpec, quat_to_matrix,
                    rain, resolve_scene, shipped_scenes)
from .settings import Settings

__all__ = [
    # simulation
    "Scene", "World", "Settings", "SOLVERS", "Recorder",
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


def __getattr__(name):
    if name == "World":
        from .world import World

        return World
    if name == "SOLVERS":
        from .solvers import SOLVERS

        return SOLVERS
    raise AttributeError(f"module 'sandbox' has no attribute {name!r}")
