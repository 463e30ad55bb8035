"""The validated, fully expanded description of a scene: plain Python and numpy.

The loader (``scene.loader``) turns a TOML file or a dict into a ``Scene``; the
world (``world.World``) turns a ``Scene`` into Taichi fields. Nothing here
imports Taichi, so scenes can be built, checked and edited without a runtime.

Frames and units: world z-up, SI units, quaternions (w, x, y, z). A body's
``position`` is its centre of mass and its ``orientation`` the orientation of its
body frame; each shape sits in the body frame at ``local_position`` /
``local_orientation``. For a single box, sphere or capsule the body frame is the
shape frame; for hulls and compounds the loader shifts shapes so the body origin
is the centre of mass.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, ClassVar

import numpy as np


RESISTANCE_KEYS = ("linear_damping", "angular_damping", "rolling_friction", "torsional_friction")
"""A body's motion resistances, all 0 by default (effects.py compiles each in only when some body
has one): damping [1/s] slows its velocity like ``v' = v / (1 + h c)`` (Box2D, Rapier); rolling and
torsional friction [m] are lever arms: a contact point resists rolling (spinning about its
normal) with a torque up to that length times its normal force (Bullet's rolling and spinning
friction)."""

DEFAULT_PIECES = 8
"""Voronoi pieces of a convex body's fracture when none is given (scene key ``pieces``)."""
MAX_PIECES = 64
"""Most pieces one fracture of a convex body may make (each is a new body and a new hull)."""


@dataclass
class ShapeSpec:
    kind: str  # "sphere" | "capsule" | "box" | "hull"
    radius: float = 0.0  # sphere, capsule [m]
    half_height: float = 0.0  # capsule: half length of the core segment along local z [m]
    half_extents: np.ndarray | None = None  # box (3,) [m]
    vertices: np.ndarray | None = None  # hull (V, 3) in the shape frame [m]
    local_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    local_orientation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    # this shape's share of its body's mass, set by the loader for bodies of two or more shapes,
    # used when the body fractures into its shapes (fracture.py): for a decomposed mesh it is the
    # mesh's material inside this hull, which differs from the hull's own volume
    piece_mass: float | None = None  # [kg]
    piece_com: np.ndarray | None = None  # (3,) body frame [m]
    piece_inertia: np.ndarray | None = None  # (3, 3) body frame, about piece_com [kg m^2]


@dataclass
class BodySpec:
    shapes: list[ShapeSpec]
    position: np.ndarray  # (3,) centre of mass, world [m]
    orientation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    linear_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # [m/s]
    angular_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # world frame [rad/s]
    mass: float = 1.0  # [kg]; ignored when static
    inertia: np.ndarray = field(default_factory=lambda: np.eye(3))  # (3,3) body frame, about the COM [kg m^2]
    static: bool = False
    friction: float = 0.5
    restitution: float = 0.0
    linear_damping: float = 0.0  # [1/s] (RESISTANCE_KEYS)
    angular_damping: float = 0.0  # [1/s]
    rolling_friction: float = 0.0  # [m] combined with the partner's by max
    torsional_friction: float = 0.0  # [m]
    name: str | None = None
    breakable: bool = False  # fractures when a contact manifold's normal impulse in one step exceeds strength
    strength: float | None = None  # [N s], breakable bodies only
    pieces: int = DEFAULT_PIECES  # Voronoi pieces when a breakable convex body breaks


@dataclass
class PlaneSpec:
    normal: np.ndarray  # (3,) unit; the solid half-space is normal . x <= offset
    offset: float = 0.0
    friction: float = 0.5
    restitution: float = 0.0


@dataclass
class MeshSpec:
    """A static non-convex triangle mesh (a file or a generated height field), world frame."""

    vertices: np.ndarray  # (V, 3) [m]
    triangles: np.ndarray  # (T, 3) int vertex indices, counter-clockwise seen from the solid's outside
    friction: float = 0.5
    restitution: float = 0.0
    name: str | None = None


@dataclass
class EventSpec:
    """One timeline entry, applied between steps at step round(time / dt), identically headless
    and in the web sandbox. ``bodies`` indexes the body list as it is when the event applies:
    scene bodies first, bodies added by earlier ``drop`` events after them, removals closing
    the gaps (the loader replays the timeline to check every index)."""

    time: float  # [s] >= 0, and <= the scene's duration when it has one
    kind: str  # "drop" | "set_velocity" | "impulse" | "remove" | "solver" | "iterations" | "gravity" | "effects"
    #            | "fracture" | "formulation" | "timestep" (interactive only: the web sandbox's dt / substeps)
    new_bodies: list = field(default_factory=list)  # drop: BodySpecs (generated, seeded)
    bodies: list = field(default_factory=list)  # set_velocity / impulse / remove: body indices
    linear_velocity: np.ndarray | None = None  # set_velocity [m/s]; None keeps it
    angular_velocity: np.ndarray | None = None  # set_velocity [rad/s]; None keeps it
    impulse: np.ndarray | None = None  # impulse [N s], world frame
    point: np.ndarray | None = None  # impulse: world point of application [m]; None = centre of mass
    solver: str | None = None  # solver: the new solver's name
    iterations: int | None = None  # solver / iterations: the new iteration count
    options: dict = field(default_factory=dict)  # solver: its options
    gravity: np.ndarray | None = None  # gravity: the new gravity vector [m/s^2]
    effects: tuple | None = None  # effects: the effects now on (a subset of keys.EFFECTS)
    dt: float | None = None  # timestep: the new step [s]
    substeps: int | None = None  # timestep: the new number of substeps
    formulation: str | None = None  # formulation: "soft-step" | "paper" (formulation.py)
    baumgarte: float | None = None  # formulation: the paper's Baumgarte factor; None keeps it
    pieces: int | None = None  # fracture: Voronoi pieces of a convex body
    seed: int | None = None  # fracture: seed of the Voronoi sites (the k-th listed body uses seed + k)
    outward_impulse: float | None = None  # fracture: [N s] total impulse pushing the pieces apart
    cause: str = "script"  # "script" (scene or API), or "impact" (a breakable body broke; World.step logs it)


@dataclass
class WorldSpec:
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))  # [m/s^2]
    dt: float = 1.0 / 60.0  # [s] time step
    substeps: int = 1  # the whole collide-solve-integrate step runs this many times per step
    contact_hertz: float | None = None  # [Hz] contact stiffness; None: Settings.contact_hertz
    duration: float | None = None  # [s] how long the scene is meant to run (events must fall inside)
    speculative_contacts: bool | None = None  # None: Settings.speculative_contacts
    speculative_speed: float | None = None  # [m/s] None: Settings.speculative_speed
    formulation: str | None = None  # "soft-step" | "paper" (formulation.py); None: Settings.formulation
    baumgarte: float | None = None  # [1] the paper formulation's position correction; None: Settings.baumgarte

    SETTINGS: ClassVar[tuple] = ("contact_hertz", "speculative_contacts", "speculative_speed", "formulation",
                                 "baumgarte")
    """The keys that a scene gives for its world's settings.Settings (None: the setting's default)."""

    def settings_given(self) -> dict:
        return {key: getattr(self, key) for key in self.SETTINGS if getattr(self, key) is not None}


@dataclass
class SolverSpec:
    name: str = "pgs"
    iterations: int = 10
    options: dict = field(default_factory=dict)


@dataclass
class Scene:
    source: str  # file path, or "<dict>"
    world: WorldSpec = field(default_factory=WorldSpec)
    solver: SolverSpec = field(default_factory=SolverSpec)
    bodies: list[BodySpec] = field(default_factory=list)
    planes: list[PlaneSpec] = field(default_factory=list)
    meshes: list[MeshSpec] = field(default_factory=list)
    events: list[EventSpec] = field(default_factory=list)  # sorted by time, stable
    effects: tuple = ("friction", "restitution")  # what the scene calls for (keys.EFFECTS); others compile away
    description: str = ""
    warnings: list = field(default_factory=list)  # what the loader repaired or fell back on, one sentence each

    # ``Scene.load(path)`` and ``Scene.from_dict(data, *, source="<dict>", base_dir=None)``: the
    # loader's entry points as class methods, attached by ``scene/__init__.py``. They are not
    # written here because the loader imports this module; this one never imports it back.
    load: ClassVar[Callable[..., Scene]]
    from_dict: ClassVar[Callable[..., Scene]]
