"""Scripted and interactive edits of a running world: which World method applies each event kind.

Events come from a scene's ``[[event]]`` table (validated by the loader, which also
resolved body names to indices) or from the web sandbox; either way ``World.apply_event``
applies them between steps and logs them, so a recording replays exactly the same edits.
This module only translates an event into the call that applies it (``edit_call``); the
world makes the call, so nothing here needs the World, and the translation is testable
without Taichi.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .errors import SandboxError


@dataclass(frozen=True)
class EditCall:
    """A public World method and its arguments."""

    method: str
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)


def edit_call(event, solver: str, solver_options: dict) -> EditCall:
    """The call that applies ``event``. ``solver`` and ``solver_options`` are the world's
    current choice: an ``iterations`` event keeps them."""
    kind = event.kind
    if kind == "drop":
        return EditCall("add_bodies", (event.new_bodies,))
    if kind == "set_velocity":
        return EditCall("set_velocity", (event.bodies, event.linear_velocity, event.angular_velocity))
    if kind == "impulse":
        return EditCall("apply_impulse", (event.bodies, event.impulse, event.point))
    if kind == "remove":
        return EditCall("remove_bodies", (event.bodies,))
    if kind == "solver":
        return EditCall("set_solver", (event.solver,), {"iterations": event.iterations, **event.options})
    if kind == "iterations":
        return EditCall("set_solver", (solver,), {"iterations": event.iterations, **solver_options})
    if kind == "gravity":
        return EditCall("set_gravity", (event.gravity,))
    if kind == "effects":
        return EditCall("set_effects", (event.effects,))
    if kind == "formulation":
        return EditCall("set_formulation", (event.formulation,), {"baumgarte": event.baumgarte})
    if kind == "timestep":
        return EditCall("set_timestep", (event.dt, event.substeps))
    if kind == "fracture":
        return EditCall("fracture", (event.bodies,), {"pieces": event.pieces, "seed": event.seed,
                                                      "impulse": event.outward_impulse or 0.0,
                                                      "impact": event.cause == "impact"})
    raise SandboxError(f"unknown event kind {kind!r}")
