"""Mass-splitting rigid-body sandbox: Tonge et al. 2012 beside PGS and projected Jacobi,
all in Taichi kernels.

    from sandbox import Scene, World
    world = World(Scene.load("scenes/pyramid_20.toml"), solver="mass-splitting", iterations=15, arch="cpu")
    world.step(600)
    world.state()["position"]

``World`` and ``SOLVERS`` are imported on first use, so the scene layer
(``sandbox.scene``) stays usable without starting Taichi.
"""

from .errors import CapacityError, SandboxError, SceneError, SimulationError
from .scene.spec import Scene
from .settings import Settings

__all__ = ["Scene", "World", "Settings", "SOLVERS", "SandboxError", "SceneError", "SimulationError", "CapacityError"]


def __getattr__(name):
    if name == "World":
        from .world import World

        return World
    if name == "SOLVERS":
        from .solvers import SOLVERS

        return SOLVERS
    raise AttributeError(f"module 'sandbox' has no attribute {name!r}")
