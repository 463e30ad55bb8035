"""Scripted and interactive edits of a running world: one function per event kind.

Events come from a scene's ``[[event]]`` table (validated by the loader, which
also resolved body names to indices) or from the web sandbox; either way they
are applied between steps through ``World.apply_event``, which logs them so a
recording replays exactly the same edits.
"""

from __future__ import annotations

from .errors import SandboxError


def apply_event(world, event) -> None:
    kind = event.kind
    if kind == "drop":
        world.add_bodies(event.new_bodies)
    elif kind == "set_velocity":
        world.set_velocity(event.bodies, event.linear_velocity, event.angular_velocity)
    elif kind == "impulse":
        world.apply_impulse(event.bodies, event.impulse, event.point)
    elif kind == "remove":
        world.remove_bodies(event.bodies)
    elif kind == "solver":
        world.set_solver(event.solver, iterations=event.iterations, **event.options)
    elif kind == "iterations":
        world.set_solver(world.solver, iterations=event.iterations, **world.solver_options)
    elif kind == "gravity":
        world.set_gravity(event.gravity)
    elif kind == "effects":
        world.set_effects(event.effects)
    elif kind == "timestep":
        world.set_timestep(event.dt, event.substeps)
    elif kind == "fracture":
        world.fracture(event.bodies, pieces=event.pieces, seed=event.seed, impulse=event.outward_impulse or 0.0,
                       impact=event.cause == "impact")
    else:
        raise SandboxError(f"unknown event kind {kind!r}")
