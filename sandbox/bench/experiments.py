"""The experiments beside the per-row protocol: convergence on a frozen problem (one settled
step solved by every solver on identical rows) and scaling over grid piles of growing size."""

from __future__ import annotations

import dataclasses
import math

from .protocol import SCALING_COLUMNS, finite, solver_label, stage_ms, time_steps


def frozen_problem(scene, arch: str, settle: int):
    """The scene settled for ``settle`` frames with serial PGS at the scene's own iteration
    count, as a new scene (bodies at the settled poses and velocities, no events), and the
    settings it ran with."""
    from ..world import World

    world = World(scene, solver="pgs", iterations=int(scene.solver.iterations), arch=arch)
    try:
        world.step(settle)
        bodies = world._live_specs()  # the settled state as BodySpecs (what World.add_bodies uses)
        # the settled contacts are the problem, not a placement: none of them is an overlap to cap
        settings = world.settings.replace(overlap_push_speed=world.settings.max_push_speed)
    finally:
        world.close()
    return dataclasses.replace(scene, bodies=bodies, events=[]), settings


def convergence(frozen, settings, solver: str, options: dict, sweeps: int, arch: str) -> dict:
    """Residual after every biased sweep on the frozen problem (one step, iterations = 1,
    warm start off, exactly ``sweeps`` sweeps: no floor,
    Settings.step_sweeps), and the solve time per sweep from a second, unrecorded run."""
    from ..errors import SandboxError
    from ..world import World

    s = settings.replace(sweeps=sweeps, warm_start=0.0, step_sweeps=0)
    out = {"solver": solver, "options": options, "sweeps": sweeps, "residual": [], "ms_per_sweep": None,
           "status": "ok"}
    for record in (True, False):
        world = World(frozen, solver=solver, iterations=1, arch=arch, settings=s, profile=not record, **options)
        try:
            world.record_residuals = record
            world.step(1)
            if record:
                out["residual"] = [finite(r) for r in world.residual_history]
                out["contacts"] = world.metrics()["contacts"]
            else:
                out["ms_per_sweep"] = 1e3 * world.profiler.total_s.get("iterate", 0.0) / sweeps
        except SandboxError as exc:
            out["status"] = f"failed: {exc}".replace("\n", " ")
            out["residual"] = out["residual"] or [finite(r) for r in world.residual_history]
            break
        finally:
            world.close()
    return out


# ---------------------------------------------------------------------------------------------- scaling
def grid_pile(n: int, seed: int = 20120801) -> dict:
    """A pile_1000-like grid of about n random boxes (half extents 0.25-0.5 m, random
    orientations, spacing 1.8 m), at most 4 layers high so it lands within ~1 s."""
    nz = 4 if n >= 64 else max(1, round(n ** (1 / 3)))
    per_layer = math.ceil(n / nz)
    nx = math.ceil(math.sqrt(per_layer))
    ny = math.ceil(per_layer / nx)
    return {
        "description": f"bench scaling pile: {nx} x {ny} x {nz} random boxes",
        "world": {"dt": 1.0 / 60.0},
        "solver": {"name": "pgs", "iterations": 10},
        "static": [{"shape": "plane", "normal": [0.0, 0.0, 1.0], "offset": 0.0, "friction": 0.5}],
        "generate": [{
            "kind": "grid", "counts": [nx, ny, nz], "spacing": 1.8,
            "origin": [-0.9 * (nx - 1), -0.9 * (ny - 1), 1.0], "shapes": ["box"],
            "half_extent_range": [0.25, 0.5], "orientation": "random", "seed": seed, "friction": 0.5,
        }],
    }


def run_scaling_point(scene, n: int, engine: str, solver: str, options: dict, k: int, arch: str, settle: int,
                      steps: int, peer=None) -> dict:
    """One scaling row: ``settle`` steps, then the timed steps; in ``peer`` (a ``sandbox.peers.Peer``)
    when one is given, else in our engine with ``solver``."""
    from ..errors import SandboxError
    from ..world import World

    row = dict.fromkeys(SCALING_COLUMNS)
    row.update(bodies_asked=n, engine=engine, solver=solver, options=solver_label("", options).strip(" []"),
               iterations=k, arch=arch, status="ok", bodies=len(scene.bodies))
    if peer is not None:
        sim = peer.open(scene, k)
        try:
            for _ in range(settle):
                sim.step()
            m = sim.metrics()
            row.update(contacts=m["contacts"], kinetic_energy=m["kinetic_energy"])
            row.update(time_steps(sim.step, steps))
        finally:
            sim.close()
        return row
    world = None
    try:
        world = World(scene, solver=solver, iterations=k, arch=arch, **options)
        row["arch"] = world.arch
        world.step(settle)
        m = world.metrics()
        row.update(contacts=m["contacts"], manifolds=m["manifolds"], kinetic_energy=m["kinetic_energy"])
        st = stage_ms(world, steps)
        row["ms_collide"] = st["ms_collide"]
        row["ms_iterations"] = st["ms_per_iteration"] * k
        row.update(time_steps(lambda: world.step(1), steps))
    except SandboxError as exc:
        row["status"] = f"failed: {exc}".replace("\n", " ")
    finally:
        if world is not None:
            world.close()
    return row

