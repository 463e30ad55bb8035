"""``sandbox bench``: what accuracy costs in time, per scene x solver x iteration count.

    sandbox bench [SCENES...] [--solvers pgs,mass-splitting,...] [--iterations 1,2,4,...]
                  [--arch cpu] [--out DIR] [--quick]

For every scene x solver x iteration count a fresh world is built and run through the
protocol of ``benchmarks/step_bench.py`` extended by the error metrics of method.md
section 3 (see docs/bench.md for how to read the outputs):

1. ``settle`` frames, metrics read after every frame (the kinetic-energy-vs-frame series;
   the first frame also compiles the kernels, reported apart as ``compile_s``);
2. ``window`` more frames, metrics after every frame: the *error* of the row, i.e. the
   mean kinetic energy of what should be at rest (and its std), max and mean penetration,
   RMS and max LCP residual of the rigid (relax) problem the step ends with, and the drift
   of a marker body (the dynamic body highest at t = 0: top of a stack, apex of a pyramid)
   between the end of the settle and the end of the window (M7);
3. ``steps`` steps with per-stage device syncs: ms/step by stage, and ms per solver
   iteration = (integrate_velocities + solve + integrate_positions + relax) / iterations;
4. ``steps`` steps without stage syncs, each step timed between device syncs: mean, median
   and p95 ms/step and steps/s (the number to compare with other engines).

An *iteration* here is a substep of a soft step (Box2D v3): gravity, warm start, one
biased sweep, position update, one relax sweep (docs/method-notes.md), so the iteration
count also sets the substep size. That changes the physics, not just the convergence, so
the convergence of the solver proper is measured apart on a *frozen* problem: each scene is
settled once with serial PGS at the scene's own iteration count, the settled state becomes
a new scene, and one step of it is solved with ``iterations=1``, ``Settings(sweeps=N,
warm_start=0)`` and ``record_residuals``: the RMS residual of the biased problem after
every sweep, for every solver, on identical rows (column ``frozen_residual`` = the residual
after as many sweeps as the row's iteration count).

Scaling: grid piles of growing size (``Scene.from_dict``), ms/step against bodies and
contact points. Peers: when pybullet is importable, every box-and-plane scene also runs in
pybullet (set up by ``sandbox/peers.py``, shared with ``benchmarks/peer_pybullet.py``) with the same dt
and ``numSolverIterations`` = iterations, through the same protocol, in the same process.

Outputs in ``--out``: ``bench.csv`` and ``bench.json`` (one row per scene x solver x
iteration count, pybullet rows included), ``scaling.csv``, and PNGs: ``pareto_<scene>``
(error vs ms/step), ``jitter_<scene>`` (kinetic energy vs frame), ``convergence_<scene>``
(frozen-problem residual vs sweep and vs solve time) and ``scaling``.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import platform
import subprocess
import time
import warnings
from pathlib import Path

import numpy as np

from .profile import STAGES

REPO = Path(__file__).resolve().parent.parent

FULL = {
    "scenes": ("stack_20", "pyramid_20", "pile_1000"),
    "solvers": None,  # every solver in SOLVERS
    "iterations": (1, 2, 4, 8, 15, 30, 60, 120, 250, 500),
    "settle": 120,
    "window": 60,
    "steps": 60,
    "scaling_sizes": (100, 300, 1000, 2000, 5000),
    "scaling_iterations": 15,
}
QUICK = {
    "scenes": ("pyramid_20",),
    "solvers": ("pgs", "mass-splitting"),
    "iterations": (1, 4, 16),
    "settle": 60,
    "window": 30,
    "steps": 30,
    "scaling_sizes": (32, 100),
    "scaling_iterations": 4,
}
"""``--quick``: the 210-box pyramid, the reference and the paper's solver, 1/4/16 iterations, and
two small piles for scaling: a smoke run of every output in about a minute on a 2-core CPU."""

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


def _finite(x):
    """A float for the tables, or None when there is nothing finite to report."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _label(solver: str, options: dict) -> str:
    return solver + (" [" + ",".join(f"{k}={v}" for k, v in options.items()) + "]" if options else "")


def _options(solver: str, shuffle: bool) -> dict:
    return {"shuffle": True} if shuffle and solver == "pgs-colored" else {}


def marker_index(scene) -> int | None:
    """The dynamic body highest at t = 0 (top of a stack, apex of a pyramid); the last on ties."""
    best, best_z = None, -math.inf
    for i, b in enumerate(scene.bodies):
        if not b.static and b.position[2] >= best_z:
            best, best_z = i, float(b.position[2])
    return best


def pybullet_peer():
    """The pybullet set-up (``sandbox.peers``), or None with the reason when pybullet is missing."""
    try:
        import pybullet  # noqa: F401
    except ImportError:
        return None, "pybullet is not importable (pip install -e '.[peers]')"
    from . import peers

    return peers, ""


def pybullet_version() -> str:
    try:
        from importlib.metadata import version

        return version("pybullet")
    except Exception:
        return "unknown"


def translatable_to_pybullet(scene) -> tuple[bool, str]:
    """Only scenes that peer_pybullet.py translates faithfully: dynamic single boxes on planes,
    friction 0.5 and no restitution everywhere (its set-up), no meshes, events or substeps."""
    if scene.meshes:
        return False, "has triangle meshes"
    if scene.events:
        return False, "has timeline events"
    if int(scene.world.substeps) != 1:
        return False, "uses [world] substeps"
    for b in scene.bodies:
        if b.static or len(b.shapes) != 1 or b.shapes[0].kind != "box":
            return False, "has bodies other than dynamic single boxes"
        if abs(b.friction - 0.5) > 1e-9 or b.restitution != 0.0:
            return False, "has friction other than 0.5 or restitution"
    for p in scene.planes:
        if abs(p.friction - 0.5) > 1e-9 or p.restitution != 0.0:
            return False, "has a plane with friction other than 0.5 or restitution"
    return True, ""


def machine() -> dict:
    info = {"platform": platform.platform(), "python": platform.python_version(), "cpu_count": os.cpu_count()}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                info["memory_gb"] = round(int(line.split()[1]) / 2**20, 1)
                break
    except OSError:
        pass
    info.setdefault("cpu", platform.processor() or platform.machine())
    try:
        info["load_average_at_start"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass
    try:
        from importlib.metadata import version

        info["taichi"] = version("taichi")
        info["numpy"] = version("numpy")
    except Exception:
        pass
    try:
        info["git"] = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"], capture_output=True,
                                     text=True, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        info["git"] = None
    return info


# ---------------------------------------------------------------------------------------------- timing
def _time_steps(step, steps: int) -> dict:
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


def _stage_ms(world, steps: int) -> dict:
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
    row.update(scene=scene_name, engine=engine, solver=solver, options=_label("", options).strip(" []"),
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
    from .errors import SandboxError
    from .world import World

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
        row.update(_stage_ms(world, steps))
        row.update(_time_steps(lambda: world.step(1), steps))
    except SandboxError as exc:  # SimulationError (diverged) or a capacity problem: keep the row, say why
        row["status"] = f"failed at step {world.step_count if world else 0}: {exc}".replace("\n", " ")
        for c in COLUMNS[COLUMNS.index("kinetic_energy"):]:
            if c != "compile_s":
                row[c] = None
    finally:
        if world is not None:
            world.close()
    return row, ke_series


class _PyBullet:
    """A scene in pybullet through peer_pybullet.pybullet_world, with our metrics' definitions."""

    def __init__(self, peer, scene, iterations: int):
        self.pb, self.cid, self.ids, self.masses, self.inertias = peer.pybullet_world(scene, iterations)
        self.peer = peer

    def step(self):
        self.pb.stepSimulation(physicsClientId=self.cid)

    def kinetic_energy(self) -> float:
        return float(self.peer.pybullet_ke(self.pb, self.cid, self.ids, self.masses, self.inertias))

    def metrics(self) -> dict:
        pts = self.pb.getContactPoints(physicsClientId=self.cid)
        pen = np.array([max(0.0, -p[8]) for p in pts]) if pts else np.zeros(0)
        return {"kinetic_energy": self.kinetic_energy(), "contacts": len(pts),
                "max_penetration": float(pen.max()) if len(pen) else 0.0,
                "mean_penetration": float(pen.mean()) if len(pen) else 0.0}

    def position(self, i: int) -> np.ndarray:
        return np.asarray(self.pb.getBasePositionAndOrientation(self.ids[i], physicsClientId=self.cid)[0])

    def close(self):
        self.pb.disconnect(physicsClientId=self.cid)


def run_pybullet(peer, scene, scene_name: str, k: int, settle: int, window: int, steps: int) -> tuple[dict, list]:
    """The same protocol in pybullet: settle, error window, timed steps (no stage times)."""
    row = _empty_row(scene_name, "pybullet", "pybullet", {}, k, "cpu")
    row["bodies"] = len(scene.bodies)
    marker = marker_index(scene)
    sim = _PyBullet(peer, scene, k)
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
        row.update(_time_steps(sim.step, steps))
    finally:
        sim.close()
    return row, ke_series


# ---------------------------------------------------------------------------------------------- convergence
def frozen_problem(scene, arch: str, settle: int):
    """The scene settled for ``settle`` frames with serial PGS at the scene's own iteration
    count, as a new scene (bodies at the settled poses and velocities, no events), and the
    settings it ran with."""
    from .world import World

    world = World(scene, solver="pgs", iterations=int(scene.solver.iterations), arch=arch)
    try:
        world.step(settle)
        bodies = world._live_specs()  # the settled state as BodySpecs (what World.add_bodies uses)
        settings = world.settings
    finally:
        world.close()
    return dataclasses.replace(scene, bodies=bodies, events=[]), settings


def convergence(frozen, settings, solver: str, options: dict, sweeps: int, arch: str) -> dict:
    """Residual after every biased sweep on the frozen problem (one step, iterations = 1,
    warm start off), and the solve time per sweep from a second, unrecorded run."""
    from .errors import SandboxError
    from .world import World

    s = settings.replace(sweeps=sweeps, warm_start=0.0)
    out = {"solver": solver, "options": options, "sweeps": sweeps, "residual": [], "ms_per_sweep": None,
           "status": "ok"}
    for record in (True, False):
        world = World(frozen, solver=solver, iterations=1, arch=arch, settings=s, profile=not record, **options)
        try:
            world.record_residuals = record
            world.step(1)
            if record:
                out["residual"] = [_finite(r) for r in world.residual_history]
                out["contacts"] = world.metrics()["contacts"]
            else:
                out["ms_per_sweep"] = 1e3 * world.profiler.total_s.get("iterate", 0.0) / sweeps
        except SandboxError as exc:
            out["status"] = f"failed: {exc}".replace("\n", " ")
            out["residual"] = out["residual"] or [_finite(r) for r in world.residual_history]
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
    from .errors import SandboxError
    from .world import World

    row = dict.fromkeys(SCALING_COLUMNS)
    row.update(bodies_asked=n, engine=engine, solver=solver, options=_label("", options).strip(" []"), iterations=k,
               arch=arch, status="ok", bodies=len(scene.bodies))
    if engine == "pybullet":
        sim = _PyBullet(peer, scene, k)
        try:
            for _ in range(settle):
                sim.step()
            m = sim.metrics()
            row.update(contacts=m["contacts"], kinetic_energy=m["kinetic_energy"])
            row.update(_time_steps(sim.step, steps))
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
        st = _stage_ms(world, steps)
        row["ms_collide"] = st["ms_collide"]
        row["ms_iterations"] = st["ms_per_iteration"] * k
        row.update(_time_steps(lambda: world.step(1), steps))
    except SandboxError as exc:
        row["status"] = f"failed: {exc}".replace("\n", " ")
    finally:
        if world is not None:
            world.close()
    return row


# ---------------------------------------------------------------------------------------------- tables
def _add_peer_ratios(rows: list[dict]) -> None:
    ref = {(r["scene"], r["iterations"]): r for r in rows if r["engine"] == "pybullet" and r["status"] == "ok"}
    for r in rows:
        p = ref.get((r["scene"], r["iterations"]))
        if r["engine"] != "sandbox" or p is None or r["status"] != "ok":
            continue
        if p["steps_per_s"]:
            r["steps_per_s_ratio_to_pybullet"] = r["steps_per_s"] / p["steps_per_s"]
        if p["kinetic_energy"]:
            r["kinetic_energy_ratio_to_pybullet"] = r["kinetic_energy"] / p["kinetic_energy"]


def cost_fits(rows: list[dict]) -> list[dict]:
    """Least-squares t(k) = t0 + k t1 of ms/step over the iteration counts (method.md 3):
    t0 is the per-step cost (collision, set-up), t1 the cost of one iteration (substep)."""
    groups: dict = {}
    for r in rows:
        if r["status"] == "ok" and r["ms_per_step"] is not None:
            groups.setdefault((r["scene"], r["engine"], r["solver"], r["options"]), []).append(r)
    fits = []
    for (scene, engine, solver, options), rs in groups.items():
        ks = np.array([r["iterations"] for r in rs], dtype=float)
        if len(set(ks)) < 2:
            continue
        t = np.array([r["ms_per_step"] for r in rs])
        t1, t0 = np.polyfit(ks, t, 1)
        fits.append({"scene": scene, "engine": engine, "solver": solver, "options": options,
                     "t0_ms": float(t0), "t1_ms_per_iteration": float(t1)})
    return fits


def _sig(v, digits: int = 5):
    v = _finite(v)
    return None if v is None else float(f"{v:.{digits}g}")


def _clean(value):
    if isinstance(value, float):
        return _finite(value)
    if isinstance(value, (np.floating, np.integer)):
        return _clean(value.item())
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    return value


def _write_csv(path: Path, columns, rows) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow(["" if r.get(c) is None else (f"{r[c]:.6g}" if isinstance(r[c], float) else r[c])
                        for c in columns])


# ---------------------------------------------------------------------------------------------- plots
ERROR_PANELS = (
    ("residual_rms", "LCP residual RMS, rigid problem [m/s]"),
    ("max_penetration", "max penetration [m]"),
    ("kinetic_energy", "resting kinetic energy [J]"),
    ("drift", "marker drift over the window [m]"),
)


def _row_label(r: dict) -> str:
    """A result row's curve label: the solver, with its options when it has any."""
    return r["solver"] + (f" [{r['options']}]" if r["options"] else "")


def _line_style(label: str) -> dict:
    return dict(ls="--", marker="s") if label == "pybullet" else dict(ls="-", marker="o")


def _finish_axes(ax, legend_size: int) -> None:
    ax.grid(True, which="both", alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=legend_size)
        _tidy_log_axes(ax)


def _save(plt, fig, path, title: str) -> None:
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _tidy_log_axes(ax) -> None:
    """Plain number labels on log axes; minor labels only where an axis spans less than a decade."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    fmt = FuncFormatter(lambda v, _: f"{v:g}")
    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() != "log":
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lo, hi = sorted(axis.get_view_interval())
        axis.set_major_formatter(fmt)
        axis.set_minor_formatter(fmt if lo > 0 and hi / lo < 10 else NullFormatter())


def _curves(rows, scene):
    out: dict = {}
    for r in rows:
        if r["scene"] == scene and r["status"] == "ok":
            out.setdefault(_row_label(r), []).append(r)
    for rs in out.values():
        rs.sort(key=lambda r: r["iterations"])
    return out


def plot_pareto(plt, rows, scene, path, meta):
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    for ax, (key, title) in zip(axes.flat, ERROR_PANELS):
        for label, rs in _curves(rows, scene).items():
            pts = [(r["ms_per_step"], r[key], r["iterations"]) for r in rs
                   if r[key] is not None and r[key] > 0 and r["ms_per_step"]]
            if not pts:
                continue
            x, y, k = zip(*pts)
            style = _line_style(label)
            ax.plot(x, y, label=label, ms=4, lw=1.2, **style)
            for xi, yi, ki in pts:
                ax.annotate(str(ki), (xi, yi), textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("ms / step (wall, device-synced)")
        zeros = {label: [str(r["iterations"]) for r in rs if r[key] == 0] for label, rs in _curves(rows, scene).items()}
        zeros = "; ".join(f"{label} x{','.join(ks)}" for label, ks in zeros.items() if ks)
        ax.set_title(title + (f"\nexactly 0, not drawn: {zeros}" if zeros else ""), fontsize=9)
        _finish_axes(ax, legend_size=7)
    _save(plt, fig, path, f"{scene}: error vs cost, one point per iteration count (label) - lower left is better\n"
          f"{meta['machine'].get('cpu', '')}, arch {meta['arch']}")


def plot_jitter(plt, rows, series, scene, path, settle):
    ks = sorted({r["iterations"] for r in rows if r["scene"] == scene})
    cols = min(len(ks), 3)
    nrows = math.ceil(len(ks) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols, 3.2 * nrows), squeeze=False, sharex=True)
    for ax, k in zip(axes.flat, ks):
        for r in rows:
            if r["scene"] != scene or r["iterations"] != k:
                continue
            ke = np.asarray([np.nan if v is None else v for v in series.get(_series_key(r), [])], dtype=float)
            if len(ke) == 0:
                continue
            label = _row_label(r)
            ax.semilogy(np.arange(1, len(ke) + 1), np.maximum(ke, 1e-12), lw=0.9, label=label,
                        ls="--" if r["engine"] == "pybullet" else "-")
        ax.axvline(settle, color="k", lw=0.6, alpha=0.5)
        ax.set_title(f"{k} iteration{'s' if k != 1 else ''}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel("frame")
        ax.set_ylabel("kinetic energy [J]")
    for ax in list(axes.flat)[len(ks):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    _save(plt, fig, path, f"{scene}: kinetic energy vs frame (no sleeping, no damping); error window right of the line")


def plot_convergence(plt, conv, scene, path):
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for c in conv:
        res = np.asarray([np.nan if v is None else v for v in c["residual"]], dtype=float)
        if not np.any(res > 0):  # no contacts: nothing to converge
            continue
        label = _label(c["solver"], c["options"])
        k = np.arange(1, len(res) + 1)
        a.loglog(k, res, lw=1.2, label=label)
        if c["ms_per_sweep"]:
            b.loglog(k * c["ms_per_sweep"], res, lw=1.2, label=label)
    a.set_xlabel("sweeps on the frozen problem (iterations = 1, warm start off)")
    b.set_xlabel("solve time [ms] (sweeps x ms/sweep)")
    for ax in (a, b):
        ax.set_ylabel("RMS residual, biased problem [m/s]")
        _finish_axes(ax, legend_size=8)
    _save(plt, fig, path, f"{scene}: convergence on one frozen step of the settled scene")


def plot_scaling(plt, rows, path, meta):
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    groups: dict = {}
    for r in rows:
        if r["status"] == "ok" and r["ms_per_step"]:
            groups.setdefault(_row_label(r), []).append(r)
    for label, rs in groups.items():
        rs.sort(key=lambda r: r["bodies"])
        style = _line_style(label)
        a.loglog([r["bodies"] for r in rs], [r["ms_per_step"] for r in rs], label=label, ms=4, **style)
        pts = [(r["contacts"], r["ms_per_step"]) for r in rs if r["contacts"]]
        if pts:
            b.loglog(*zip(*pts), label=label, ms=4, **style)
    a.set_xlabel("bodies")
    b.set_xlabel("contact points (after the settle)")
    for ax in (a, b):
        ax.set_ylabel("ms / step")
        _finish_axes(ax, legend_size=8)
    _save(plt, fig, path, f"scaling on grid piles, {meta['scaling_iterations']} iterations, arch {meta['arch']}, "
          f"{meta['machine'].get('cpu', '')}")


def write_plots(doc: dict, out) -> list[Path]:
    """Every PNG from a bench document alone (``bench.json`` can be re-plotted without re-running:
    ``sandbox.bench.write_plots(json.load(open("bench.json")), "dir")``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    meta = doc["meta"]
    settle = meta["config"]["settle"]
    scenes = list(dict.fromkeys(r["scene"] for r in doc["rows"]))
    pngs = []
    for name in scenes:
        pngs.append(out / f"pareto_{name}.png")
        plot_pareto(plt, doc["rows"], name, pngs[-1], meta)
        pngs.append(out / f"jitter_{name}.png")
        plot_jitter(plt, doc["rows"], doc["series_kinetic_energy"], name, pngs[-1], settle)
        pngs.append(out / f"convergence_{name}.png")
        plot_convergence(plt, doc["convergence"].get(name, []), name, pngs[-1])
    if doc["scaling"]:
        pngs.append(out / "scaling.png")
        plot_scaling(plt, doc["scaling"], pngs[-1], meta)
    return pngs


def _series_key(r) -> str:
    return f"{r['scene']}|{r['solver']}{'|' + r['options'] if r['options'] else ''}|{r['iterations']}"


# ---------------------------------------------------------------------------------------------- driver
def resolve_config(quick: bool, **given) -> dict:
    from .solvers import SOLVERS

    base = QUICK if quick else FULL
    cfg = {k: (given.get(k) if given.get(k) not in (None, [], ()) else base[k]) for k in base}
    cfg["solvers"] = tuple(cfg["solvers"] or SOLVERS)
    for k in ("iterations", "scaling_sizes"):
        cfg[k] = tuple(int(x) for x in cfg[k])
    return cfg


def command_line(cfg: dict, arch: str, out: str, shuffle: bool, peers: bool, scaling: bool) -> str:
    parts = ["sandbox bench", *cfg["scenes"], "--solvers", ",".join(cfg["solvers"]),
             "--iterations", ",".join(map(str, cfg["iterations"])), "--settle", str(cfg["settle"]),
             "--window", str(cfg["window"]), "--steps", str(cfg["steps"]), "--arch", arch]
    if scaling:
        parts += ["--scaling-sizes", ",".join(map(str, cfg["scaling_sizes"])),
                  "--scaling-iterations", str(cfg["scaling_iterations"])]
    else:
        parts.append("--no-scaling")
    if shuffle:
        parts.append("--shuffle")
    if not peers:
        parts.append("--no-peers")
    return " ".join(parts + ["--out", out])


def run(scenes=None, solvers=None, iterations=None, arch: str = "cpu", out="out/bench", quick: bool = False,
        settle=None, window=None, steps=None, scaling_sizes=None, scaling_iterations=None, shuffle: bool = False,
        peers: bool = True, scaling: bool = True, quiet: bool = False, echo=print) -> dict:
    """Run the whole bench, write the tables and plots into ``out``, return the JSON document."""
    from tqdm import tqdm

    from . import Scene, backend
    from .scene.library import resolve_scene
    from .errors import SandboxError
    from .solvers import SOLVERS

    try:
        import matplotlib  # noqa: F401  (fail before a long run, not after it)
    except ImportError:
        raise SandboxError("sandbox bench draws its plots with matplotlib: pip install -e '.[plots]'") from None
    cfg = resolve_config(quick, scenes=scenes, solvers=solvers, iterations=iterations, settle=settle, window=window,
                         steps=steps, scaling_sizes=scaling_sizes, scaling_iterations=scaling_iterations)
    for s in cfg["solvers"]:
        if s not in SOLVERS:
            raise SandboxError(f"unknown solver {s!r}; choose from {', '.join(SOLVERS)}")
    for key in ("iterations", "scaling_sizes"):
        if any(v < 1 for v in cfg[key]):
            raise SandboxError(f"--{key.replace('_', '-')} must be positive integers, got {cfg[key]}")
    for key in ("settle", "window", "steps", "scaling_iterations"):
        if int(cfg[key]) < 1:
            raise SandboxError(f"--{key.replace('_', '-')} must be >= 1, got {cfg[key]}")
    loaded = [(Path(resolve_scene(name)).stem, Scene.load(resolve_scene(name))) for name in cfg["scenes"]]
    arch = backend.init(arch)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    peer, peer_note = (pybullet_peer() if peers else (None, "peers switched off (--no-peers)"))
    pb_scenes = {}
    for name, scene in loaded:
        ok, why = translatable_to_pybullet(scene) if peer else (False, peer_note)
        pb_scenes[name] = ok
        if peer and not ok:
            echo(f"bench: pybullet skips {name}: it {why}")
    if not peer:
        echo(f"bench: no pybullet rows: {peer_note}")
    ks = cfg["iterations"]
    sweeps = max(ks)
    sizes = cfg["scaling_sizes"] if scaling else ()
    units = (len(loaded) * len(cfg["solvers"]) * (len(ks) + 1) + sum(pb_scenes.values()) * len(ks)
             + len(sizes) * (len(cfg["solvers"]) + (1 if peer else 0)) + len(loaded))
    meta = {
        "command": command_line(cfg, arch, str(out), shuffle, peers, scaling),
        "config": {k: list(v) if isinstance(v, tuple) else v for k, v in cfg.items()},
        "arch": arch, "shuffle": shuffle, "machine": machine(), "scaling_iterations": cfg["scaling_iterations"],
        "pybullet": pybullet_version() if peer else None, "pybullet_note": peer_note or None,
        "frozen_problem": f"each scene settled {cfg['settle']} frames with pgs at the scene's own iteration count, "
                          f"then one step with iterations=1, Settings(sweeps={sweeps}, warm_start=0), "
                          "record_residuals: RMS residual of the biased problem after every sweep",
        "started": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    rows, series, conv, scaling_rows = [], {}, {}, []
    t_start = time.perf_counter()
    bar = tqdm(total=units, desc="bench", unit="run", disable=quiet)
    for name, scene in loaded:
        for solver in cfg["solvers"]:
            options = _options(solver, shuffle)
            for k in ks:
                bar.set_postfix_str(f"{name} {solver} x{k}")
                row, ke = run_sandbox(scene, name, solver, options, k, arch, cfg["settle"], cfg["window"],
                                      cfg["steps"])
                rows.append(row)
                series[_series_key(row)] = ke
                bar.update()
        if pb_scenes[name]:
            for k in ks:
                bar.set_postfix_str(f"{name} pybullet x{k}")
                row, ke = run_pybullet(peer, scene, name, k, cfg["settle"], cfg["window"], cfg["steps"])
                rows.append(row)
                series[_series_key(row)] = ke
                bar.update()
        bar.set_postfix_str(f"{name} frozen problem")
        frozen, settings = frozen_problem(scene, arch, cfg["settle"])
        bar.update()
        conv[name] = []
        for solver in cfg["solvers"]:
            bar.set_postfix_str(f"{name} {solver} convergence")
            options = _options(solver, shuffle)
            c = convergence(frozen, settings, solver, options, sweeps, arch)
            conv[name].append(c)
            for row in rows:
                if (row["scene"], row["engine"], row["solver"]) == (name, "sandbox", solver) \
                        and row["iterations"] <= len(c["residual"]):
                    row["frozen_residual"] = c["residual"][row["iterations"] - 1]
            bar.update()
    for n in sizes:
        scene = Scene.from_dict(grid_pile(n), source=f"<bench scaling pile {n}>")
        for solver in cfg["solvers"]:
            bar.set_postfix_str(f"scaling {len(scene.bodies)} bodies, {solver}")
            scaling_rows.append(run_scaling_point(scene, n, "sandbox", solver, _options(solver, shuffle),
                                                  cfg["scaling_iterations"], arch, cfg["settle"], cfg["steps"]))
            bar.update()
        if peer:
            bar.set_postfix_str(f"scaling {len(scene.bodies)} bodies, pybullet")
            scaling_rows.append(run_scaling_point(scene, n, "pybullet", "pybullet", {}, cfg["scaling_iterations"],
                                                  "cpu", cfg["settle"], cfg["steps"], peer=peer))
            bar.update()
    bar.close()
    _add_peer_ratios(rows)
    meta["wall_s"] = time.perf_counter() - t_start
    for curves in conv.values():  # per-frame and per-sweep series to 5 significant digits (file size)
        for c in curves:
            c["residual"] = [_sig(v) for v in c["residual"]]
    series = {key: [_sig(v) for v in values] for key, values in series.items()}
    doc = _clean({"meta": meta, "columns": list(COLUMNS), "rows": rows, "cost_fits": cost_fits(rows),
                  "convergence": conv, "scaling": scaling_rows, "series_kinetic_energy": series})
    _write_csv(out / "bench.csv", COLUMNS, doc["rows"])
    _write_csv(out / "scaling.csv", SCALING_COLUMNS, doc["scaling"])
    (out / "bench.json").write_text(json.dumps(doc, separators=(",", ":")))
    pngs = write_plots(doc, out)
    _print_summary(doc, cfg, out, pngs, echo)
    return doc


def _fmt(v, spec):
    digits = "".join(ch for ch in spec.split(".")[0] if ch.isdigit())
    width = int(digits or 0)
    return "-".rjust(width) if v is None else format(v, spec)


def _print_summary(doc, cfg, out, pngs, echo) -> None:
    meta = doc["meta"]
    m = meta["machine"]
    echo(f"# {m.get('cpu')} ({m.get('cpu_count')} cores), arch {meta['arch']}, taichi {m.get('taichi')}, "
         f"pybullet {meta['pybullet'] or '-'}; settle {cfg['settle']}, window {cfg['window']}, "
         f"timed {cfg['steps']} steps; {meta['wall_s']:.0f} s")

    def label(r):
        return r["solver"] + ("+" + r["options"] if r["options"] else "")

    ws = max([12] + [len(r["scene"]) for r in doc["rows"]])
    wl = max([20] + [len(label(r)) for r in doc["rows"] + doc["scaling"]])
    echo(f"{'scene':{ws}s} {'solver':{wl}s} {'it':>4s} {'contacts':>8s} {'ms/step':>8s} {'steps/s':>8s} "
         f"{'ms/iter':>8s} {'KE [J]':>9s} {'pen max':>9s} {'res rms':>9s} {'frozen':>9s} {'drift':>9s} "
         f"{'x pb s/s':>8s} {'x pb KE':>8s}")
    for r in doc["rows"]:
        if r["status"] != "ok":
            echo(f"{r['scene']:{ws}s} {label(r):{wl}s} {r['iterations']:4d} {r['status']}")
            continue
        echo(f"{r['scene']:{ws}s} {label(r):{wl}s} {r['iterations']:4d} {r['contacts']:8d} {r['ms_per_step']:8.2f} "
             f"{r['steps_per_s']:8.1f} {_fmt(r['ms_per_iteration'], '8.3f')} {r['kinetic_energy']:9.2e} "
             f"{r['max_penetration']:9.2e} {_fmt(r['residual_rms'], '9.2e')} {_fmt(r['frozen_residual'], '9.2e')} "
             f"{_fmt(r['drift'], '9.2e')} {_fmt(r['steps_per_s_ratio_to_pybullet'], '8.3g')} "
             f"{_fmt(r['kinetic_energy_ratio_to_pybullet'], '8.1e')}")
    for f in doc["cost_fits"]:
        echo(f"cost fit   {f['scene']:{ws}s} {label(f):{wl}s} "
             f"t(k) = {f['t0_ms']:.2f} ms + k x {f['t1_ms_per_iteration']:.3f} ms")
    for r in doc["scaling"]:
        if r["status"] == "ok":
            echo(f"scaling    {r['bodies']:5d} bodies {_fmt(r['contacts'], '6d')} contacts  "
                 f"{label(r):{wl}s} {r['ms_per_step']:8.2f} ms/step")
        else:
            echo(f"scaling    {r['bodies']:5d} bodies {label(r):{wl}s} {r['status']}")
    echo(f"wrote      {out / 'bench.csv'}, {out / 'bench.json'}, {out / 'scaling.csv'}, "
         f"{len(pngs)} PNGs in {out}")
