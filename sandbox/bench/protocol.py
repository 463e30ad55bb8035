"""The measurement protocol of one row: a fresh world (ours or a peer's) through settle, error
window and timed steps (``sandbox/bench/__init__.py`` lists the four phases), and the columns
the rows are made of.

Every function here takes a scene and numbers and returns a row; nothing is written to disk.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..profile import STAGES

PER_ITERATION_STAGES = ("integrate_velocities", "iterate", "integrate_positions", "relax")
"""The stages that run once per iteration (substep); ``prepare`` and the collision run once per step."""

COLUMNS = (
    "scene", "engine", "solver", "options", "iterations", "arch", "status", "bodies", "contacts", "manifolds",
    # error (the measurement window after the settle)
    "kinetic_energy", "kinetic_energy_std", "max_penetration", "mean_penetration", "residual_rms",
    "residual_max", "frozen_residual", "drift", "drift_xy", "drift_z", "drift_rate_mm_s",
    # cost
    "ms_per_step", "ms_per_step_median", "ms_per_step_p95", "steps_per_s", "ms_per_iteration",
    *(f"ms_{s}" for s in STAGES), "ms_collide", "ms_profiled_total", "compile_s",
    # peers, side by side in the same run
    "steps_per_s_ratio_to_pybullet", "kinetic_energy_ratio_to_pybullet",
)
REFERENCE_PEER = "pybullet"
"""The peer engine (``sandbox.peers.PEERS``) the bench runs beside our solvers; the ``*_ratio_to_pybullet``
columns divide by its rows."""
NOT_MEASURED_FOR_PYBULLET = frozenset(
    ["manifolds", "residual_rms", "residual_max", "frozen_residual", "ms_per_iteration", "compile_s",
     "ms_collide", "ms_profiled_total", "steps_per_s_ratio_to_pybullet", "kinetic_energy_ratio_to_pybullet",
     *(f"ms_{s}" for s in STAGES)]
)
"""Columns left empty in pybullet rows: pybullet exposes neither its LCP residual nor per-stage
times, and the ratio columns are relative to pybullet itself."""

SCALING_COLUMNS = ("bodies_asked", "engine", "solver", "options", "iterations", "arch", "status", "bodies", "contacts",
                   "manifolds", "ms_per_step", "ms_per_step_median", "ms_per_step_p95", "steps_per_s", "ms_collide",
                   "ms_iterations", "kinetic_energy")


# ---------------------------------------------------------------------------------------------- helpers
def _sync() -> None:
    import taichi as ti

    ti.sync()


def finite(x):
    """A float for the tables, or None when there is nothing finite to report."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def solver_label(solver: str, options: dict) -> str:
    """``pgs-colored [shuffle=True]``: a solver with its options, for curve labels and the options column."""
    return solver + (" [" + ",".join(f"{k}={v}" for k, v in options.items()) + "]" if options else "")


def marker_index(scene) -> int | None:
    """The dynamic body highest at t = 0 (top of a stack, apex of a pyramid); the last on ties."""
    best, best_z = None, -math.inf
    for i, b in enumerate(scene.bodies):
        if not b.static and b.position[2] >= best_z:
            best, best_z = i, float(b.position[2])
    return best


# ---------------------------------------------------------------------------------------------- timing
def time_steps(step, steps: int) -> dict:
    """Per-step wall time with a device sync after every step: mean, median, p95, steps/s."""
    times = np.empty(steps)
    _sync()
    for i in range(steps):
        t = time.perf_counter()
        step()
        _sync()
        times[i] = time.perf_counter() - t
    return {"ms_per_step": 1e3 * times.mean(), "ms_per_step_median": 1e3 * float(np.median(times)),
            "ms_per_step_p95": 1e3 * float(np.percentile(times, 95)), "steps_per_s": steps / times.sum()}


def stage_ms(world, steps: int) -> dict:
    """ms/step of every stage, with the per-stage device syncs of the profiler (read from the
    raw stage totals: ``timing_ms()`` folds prepare and relax into its ``solve`` group)."""
    p = world.profiler
    p.enabled = True
    world.step(1)  # with the profiler on the iteration loop runs stage by stage: compile that outside the timing
    p.reset()
    world.step(steps)
    p.enabled = False
    n = max(1, p.steps)
    ms = {s: 1e3 * p.total_s.get(s, 0.0) / n for s in STAGES}
    out = {f"ms_{s}": v for s, v in ms.items()}
    out["ms_collide"] = ms["broadphase"] + ms["narrowphase"]
    out["ms_profiled_total"] = sum(ms.values())
    out["ms_per_iteration"] = sum(ms[s] for s in PER_ITERATION_STAGES) / world.iterations
    return out


# ---------------------------------------------------------------------------------------------- one run
def _empty_row(scene_name, engine, solver, options, k, arch) -> dict:
    row = dict.fromkeys(COLUMNS)
    row.update(scene=scene_name, engine=engine, solver=solver, options=solver_label("", options).strip(" []"),
               iterations=k, arch=arch, status="ok")
    return row


def _window_error(row, samples: list[dict], marker, p_settled, p_end, window_s) -> None:
    ke = np.array([s["kinetic_energy"] for s in samples])
    row["kinetic_energy"] = float(ke.mean())
    row["kinetic_energy_std"] = float(ke.std())
    row["max_penetration"] = max(s["max_penetration"] for s in samples)
    row["mean_penetration"] = float(np.mean([s["mean_penetration"] for s in samples]))
    if "residual_rms" in samples[0]:
        row["residual_rms"] = float(np.mean([s["residual_rms"] for s in samples]))
        row["residual_max"] = max(s["residual_max"] for s in samples)
    if marker is not None:
        d = np.asarray(p_end, dtype=np.float64) - np.asarray(p_settled, dtype=np.float64)
        row["drift"] = float(np.linalg.norm(d))
        row["drift_xy"] = float(np.linalg.norm(d[:2]))
        row["drift_z"] = float(d[2])
        row["drift_rate_mm_s"] = 1e3 * row["drift"] / window_s


def run_sandbox(scene, scene_name: str, solver: str, options: dict, k: int, arch: str, settle: int, window: int,
                steps: int) -> tuple[dict, list]:
    """One row of the table for our engine, and its kinetic-energy-vs-frame series."""
    from ..errors import SandboxError
    from ..world import World

    row = _empty_row(scene_name, "sandbox", solver, options, k, arch)
    ke_series: list[float] = []
    marker = marker_index(scene)
    world = None
    try:
        t0 = time.perf_counter()
        world = World(scene, solver=solver, iterations=k, arch=arch, profile=False, **options)
        row["arch"] = world.arch
        row["bodies"] = world.body_count
        world.step(1)
        _sync()
        row["compile_s"] = time.perf_counter() - t0
        ke_series.append(world.metrics()["kinetic_energy"])
        for _ in range(settle - 1):
            world.step(1)
            ke_series.append(world.metrics()["kinetic_energy"])
        p_settled = world.state()["position"][marker] if marker is not None else None
        samples = []
        for _ in range(window):
            world.step(1)
            m = world.metrics()
            samples.append(m)
            ke_series.append(m["kinetic_energy"])
        p_end = world.state()["position"][marker] if marker is not None else None
        _window_error(row, samples, marker, p_settled, p_end, window * world.dt)
        row["contacts"], row["manifolds"] = samples[-1]["contacts"], samples[-1]["manifolds"]
        row.update(stage_ms(world, steps))
        row.update(time_steps(lambda: world.step(1), steps))
    except SandboxError as exc:  # SimulationError (diverged) or a capacity problem: keep the row, say why
        row["status"] = f"failed at step {world.step_count if world else 0}: {exc}".replace("\n", " ")
        for c in COLUMNS[COLUMNS.index("kinetic_energy"):]:
            if c != "compile_s":
                row[c] = None
    finally:
        if world is not None:
            world.close()
    return row, ke_series


def run_peer(peer, scene, scene_name: str, k: int, settle: int, window: int, steps: int) -> tuple[dict, list]:
    """The same protocol in a peer engine (``sandbox.peers.Peer``): settle, error window, timed
    steps (no stage times); the peer's name fills the engine and solver columns."""
    row = _empty_row(scene_name, peer.name, peer.name, {}, k, "cpu")
    row["bodies"] = len(scene.bodies)
    marker = marker_index(scene)
    sim = peer.open(scene, k)
    ke_series = []
    try:
        for _ in range(settle):
            sim.step()
            ke_series.append(sim.kinetic_energy())
        p_settled = sim.position(marker) if marker is not None else None
        samples = []
        for _ in range(window):
            sim.step()
            m = sim.metrics()
            samples.append(m)
            ke_series.append(m["kinetic_energy"])
        p_end = sim.position(marker) if marker is not None else None
        _window_error(row, samples, marker, p_settled, p_end, window * float(scene.world.dt))
        row["contacts"] = samples[-1]["contacts"]
        row.update(time_steps(sim.step, steps))
    finally:
        sim.close()
    return row, ke_series


def series_key(r) -> str:
    """A row's key in the document's kinetic-energy series (scene, solver, options, iterations)."""
    return f"{r['scene']}|{r['solver']}{'|' + r['options'] if r['options'] else ''}|{r['iterations']}"

