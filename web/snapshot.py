"""What the simulation thread publishes (``Snapshot``) and how it describes the parts a user
can look into: a step paused inside (``inspection_view``) and the compare view's second world
(``twin_view``). Immutable once built, read by the render loop and the panel on their threads.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from sandbox import SandboxError, Scene


@dataclass(frozen=True)
class Snapshot:
    """What the render loop needs from one step; never mutated after publication."""

    world_id: int  # bumps when the world is rebuilt (scene change, reset)
    generation: int  # bumps when the body list changes (drop, remove, fracture, reset)
    step: int
    positions: np.ndarray  # (N, 3) float32
    orientations: np.ndarray  # (N, 4) float32, w x y z
    speeds: np.ndarray  # (N,) float32 [m/s]
    asleep: np.ndarray  # (N,) bool: bodies of sleeping islands (drawn dimmed)
    bodies: tuple  # BodySpecs of this generation (shared, read-only)
    scene: Scene
    metrics: dict
    history: dict  # "step", "kinetic_energy", "residual_rms": (F,) arrays of the last HISTORY frames
    timing_ms: dict  # ms by stage of one sampled step per stats window; "total": mean ms/step of the others
    steps_per_second: float
    realtime_factor: float
    solver: str
    iterations: int
    formulation: str  # "soft-step" | "paper" (sandbox/formulation.py)
    dt: float
    substeps: int
    effects: tuple
    gravity_on: bool
    playing: bool
    recording: bool
    contacts: dict | None = None  # "point", "normal" when contact drawing is on
    inspection: dict | None = None  # a step paused after a sweep (Simulation.inspect): what it shows
    twin: "Twin | None" = None  # the compare view's second world (Simulation.compare)
    error: str | None = None  # the last SimulationError, until the world plays again


@dataclass(frozen=True)
class Twin:
    """The compare view's second world, as the view draws it (WorldView reads these names)."""

    world_id: int
    generation: int
    positions: np.ndarray
    orientations: np.ndarray
    speeds: np.ndarray
    asleep: np.ndarray
    bodies: tuple
    scene: Scene
    solver: str
    history: np.ndarray  # its kinetic energy at the steps of Snapshot.history["step"]
    offset: float  # [m] along +x from the first world
    contacts: None = None
    inspection: None = None


COMPARE_GAP = 4.0  # [m] between the two worlds of the compare view


def describe(sweep) -> str:
    """A paused step's place, in words (the panel's heading)."""
    text = (f"substep {sweep.substep + 1}/{sweep.substeps}: {sweep.phase} sweep {sweep.index + 1}/{sweep.count}")
    return text + (" (it also applied the next substep's warm start)" if sweep.carries_warm_start else "")


def inspection_view(inspection, world, body: int | None) -> dict | None:
    """What the panel and the view show of a paused step (None when no step is paused):
    ``label``, the RMS ``residuals`` after each sweep, the ``contacts`` and, for ``body``, its
    ``sub_bodies`` (sandbox.inspection.StepInspection)."""
    if inspection is None or inspection.sweep is None:
        return None
    view = {"label": f"step {world.step_count + 1}, " + describe(inspection.sweep),
            "residuals": np.asarray(inspection.residuals, dtype=np.float64),
            "contacts": inspection.contacts(), "body": body, "sub_bodies": None}
    if body is not None:
        try:
            view["sub_bodies"] = inspection.sub_bodies(body)
        except SandboxError:  # a static body has no sub-bodies
            pass
    return view


def twin_view(world, world_id: int, generation: int, energies: Iterable[float], offset: float) -> Twin | None:
    """The compare view's second ``world`` as the view draws it (None when the view is off)."""
    if world is None:
        return None
    st = world.state(("position", "orientation", "linear_velocity"))
    return Twin(world_id=world_id, generation=generation,
                positions=st["position"].astype(np.float32), orientations=st["orientation"].astype(np.float32),
                speeds=np.linalg.norm(st["linear_velocity"], axis=1).astype(np.float32), asleep=world.asleep(),
                bodies=world.body_specs, scene=world.scene, solver=world.solver,
                history=np.asarray(list(energies), dtype=np.float64), offset=offset)
