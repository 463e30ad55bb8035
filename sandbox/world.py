"""World: owns the Taichi data of one scene and runs the step.

The step, stage by stage (names = profile keys = report keys):

1. ``integrate_velocities``  gravity and implicit gyroscopic term, world inertia
2. ``broadphase``            AABBs, hash grid, candidate pairs (broadphase.py)
3. ``narrowphase``           manifolds into the contact buffer (contacts.py)
4. ``prepare``               rows, then warm-start matching (solvers/rows.py, persistence.py)
5. ``solve``                 the chosen schedule (solvers/), then impulses stored
6. ``integrate_positions``   symplectic Euler, quaternion renormalisation, finite guard

Python only orchestrates: the cost of a step is a fixed number of kernel
launches (plus one per colour per iteration for ``pgs-colored``, and one per
iteration for the Jacobi family), and two small reads: buffer counters after
the narrowphase (a buffer that overflowed is grown and the step redone from the
saved state) and the error bits at the end (non-finite state: the last good
state is restored and a SimulationError names the body and the stage).
``substeps`` repeats the whole step with dt / substeps.
"""

from __future__ import annotations

import numpy as np
import taichi as ti

from . import backend
from .errors import CapacityError, SandboxError, SimulationError
from .profile import Profiler
from .scene.spec import Scene
from .settings import Settings
from .solvers import SOLVERS, check_solver

MAX_GROWTH_RETRIES = 6


class World:
    """A simulated scene. ``World(scene, solver=..., iterations=..., arch=...)``."""

    def __init__(self, scene: Scene, solver: str | None = None, iterations: int | None = None, arch: str = "auto",
                 settings: Settings | None = None, profile: bool = False, **solver_options):
        if not isinstance(scene, Scene):
            raise SandboxError(f"World needs a Scene (Scene.load(path) or Scene.from_dict(d)), got {type(scene).__name__}")
        self.arch = backend.init(arch)
        self.scene = scene
        self.settings = settings or Settings()
        self.dt = float(scene.world.dt)
        self.substeps = int(scene.world.substeps)
        self.gravity = np.asarray(scene.world.gravity, dtype=np.float32)
        self.profiler = Profiler(profile)
        self.step_count = 0
        from .build import build_world_data

        self._data = build_world_data(scene, self.settings)
        self.body_count = len(scene.bodies)
        self._make_buffers(self._data.initial_pair_capacity)
        opts = dict(scene.solver.options)
        opts.update(solver_options)
        self.set_solver(solver or scene.solver.name, iterations=iterations or scene.solver.iterations, **opts)

    # ------------------------------------------------------------------ buffers
    def _make_buffers(self, pair_capacity: int) -> None:
        from .broadphase import Broadphase
        from .contacts import Contacts
        from .integrate import ErrorFlags
        from .metrics import MetricBuffer
        from .persistence import ContactHistory, clear_history
        from .solvers.blocks import BlockScratch
        from .solvers.pgs import Coloring
        from .solvers.rows import Rows

        d = self._data
        shape_cap = d.shapes.capacity
        body_cap = d.bodies.capacity
        self.pair_capacity = pair_capacity
        self.bp = Broadphase(shape_cap, d.entry_capacity, pair_capacity, d.static_grid)
        self.bp.cell_size[None] = d.cell_size
        from .broadphase import compute_all_aabbs

        compute_all_aabbs(self.bp, d.shapes, d.bodies, self.settings.contact_margin)
        self.contacts = Contacts(pair_capacity, shape_cap)
        cap = self.contacts.capacity
        self.rows = Rows(cap)
        self.history = ContactHistory(cap, shape_cap)
        clear_history(self.history)
        self.blocks = BlockScratch(cap, body_cap)
        self.coloring = Coloring(pair_capacity, body_cap)
        self.errors = ErrorFlags()
        self.metric_buffer = MetricBuffer()

    # ------------------------------------------------------------------ solver
    def set_solver(self, name: str, iterations: int | None = None, **options) -> None:
        """Switch solver between steps; the world and its warm-start impulses are kept."""
        iterations = self.iterations if iterations is None else iterations
        self.solver_options = check_solver(name, iterations, options)
        self.solver = name
        self.iterations = iterations

    # ------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise SandboxError(f"step count must be a non-negative integer, got {n!r}")
        h = self.dt / self.substeps
        for _ in range(int(n)):
            for _ in range(self.substeps):
                self._substep(h)
            self.step_count += 1
            self.profiler.steps += 1

    def _substep(self, h: float) -> None:
        from .bodies import restore_good_state, save_good_state
        from .integrate import integrate_positions, integrate_velocities
        from .persistence import match_contacts, store_contacts
        from .solvers.rows import prepare_rows

        d, s, p = self._data, self.settings, self.profiler
        save_good_state(d.bodies)
        self.errors.clear()
        with p.stage("integrate_velocities"):
            integrate_velocities(d.bodies, ti.math.vec3(*self.gravity), h, True)
        for attempt in range(MAX_GROWTH_RETRIES + 1):
            self._collide()
            grown = self._grow_if_needed()
            if not grown:
                break
            restore_good_state(d.bodies)
            integrate_velocities(d.bodies, ti.math.vec3(*self.gravity), h, True)
        else:
            raise CapacityError("contact buffers kept overflowing after growing; the scene is too dense")
        with p.stage("prepare"):
            prepare_rows(self.rows, self.contacts, d.bodies, h, s.slop, s.baumgarte, s.max_push_speed,
                         s.restitution_threshold)
            match_contacts(self.history, self.contacts, self.rows, d.bodies, d.shapes, s.match_distance, s.warm_start)
        with p.stage("solve"):
            self._solve()
            store_contacts(self.history, self.contacts, self.rows, d.bodies, d.shapes)
        with p.stage("integrate_positions"):
            integrate_positions(d.bodies, h, self.errors)
        flags = int(self.errors.flags[None])
        if flags:
            body = int(self.errors.body[None])
            restore_good_state(d.bodies)
            stage = "solve (velocity)" if flags & 1 else "integrate_positions (pose)"
            name = self.body_name(body)
            raise SimulationError(
                f"step {self.step_count}: non-finite {stage} of body {body}{name}; "
                "the world was restored to its last good state"
            )

    def _collide(self) -> None:
        from .broadphase import build_dynamic_grid, find_pairs
        from .contacts import collide_pairs

        d, p = self._data, self.profiler
        with p.stage("broadphase"):
            build_dynamic_grid(self.bp, d.shapes, d.bodies, self.settings.contact_margin)
            find_pairs(self.bp, d.shapes)
        with p.stage("narrowphase"):
            collide_pairs(self.contacts, self.bp, d.shapes, d.bodies, d.pool, self.settings.contact_margin)

    def _grow_if_needed(self) -> bool:
        entries = int(self.bp.entry_total[None])
        pairs = int(self.bp.pair_total[None])
        grown = False
        if entries > self.bp.entry_capacity:
            self._data.entry_capacity = 2 * entries
            grown = True
        if pairs > self.pair_capacity:
            grown = True
        if grown:
            self._make_buffers(max(self.pair_capacity, 2 * pairs))
        return grown

    def _solve(self) -> None:
        from .solvers import blocks, pgs

        name, it = self.solver, self.iterations
        kind = blocks.PER_POINT if SOLVERS[name].block == "point" else blocks.PER_MANIFOLD
        split = name in ("mass-splitting", "block-mass-splitting")
        omega = self.solver_options.get("relaxation") or self.settings.jacobi_relaxation
        mode = blocks.MODE_SPLIT if split else blocks.MODE_JACOBI
        b, rows, c, bodies = self.blocks, self.rows, self.contacts, self._data.bodies
        blocks.build_adjacency(b, c, bodies, kind, mode, float(omega))
        if self.settings.warm_start > 0.0:
            blocks.warm_start(b, rows, c, bodies, kind)
        if name == "pgs":
            pgs.pgs_serial(rows, c, bodies, it)
        elif name == "pgs-colored":
            o = self.solver_options
            pgs.color_manifolds(self.coloring, c, bodies, int(o["shuffle"]), int(o["seed"]), self.step_count)
            starts = self.coloring.color_start.to_numpy()
            n_colors = int(self.coloring.color_count[None])
            self.last_color_count = n_colors
            for _ in range(it):
                for k in range(n_colors):
                    pgs.solve_color(rows, c, bodies, self.coloring, int(starts[k]), int(starts[k + 1]))
                if starts[pgs.MAX_COLORS + 1] > starts[pgs.MAX_COLORS]:
                    pgs.solve_overflow(rows, c, bodies, self.coloring, int(starts[pgs.MAX_COLORS]),
                                       int(starts[pgs.MAX_COLORS + 1]))
        else:
            for _ in range(it):
                blocks.jacobi_sweep(b, rows, c, bodies, kind)

    # ------------------------------------------------------------------ queries
    def body_name(self, i: int) -> str:
        if 0 <= i < self.body_count and self.scene.bodies[i].name:
            return f" ({self.scene.bodies[i].name!r})"
        return ""

    def state(self) -> dict[str, np.ndarray]:
        """Body state as numpy arrays, one row per scene body: position (N,3) [m, centre of
        mass], orientation (N,4) [w, x, y, z], linear_velocity (N,3) [m/s], angular_velocity
        (N,3) [rad/s, world frame]."""
        st = self._data.bodies.state_numpy()
        return {k: v[: self.body_count].copy() for k, v in st.items()}

    def metrics(self) -> dict[str, float]:
        from .metrics import KE, MAX_PEN, RES_MAX_SQ, RES_SQ_SUM, SUM_PEN, compute_metrics
        from .solvers.rows import compute_residuals

        compute_residuals(self.rows, self.contacts, self._data.bodies)
        compute_metrics(self.metric_buffer, self._data.bodies, self.contacts, self.rows)
        v = self.metric_buffer.values.to_numpy().astype(np.float64)
        n = int(self.contacts.count[None])
        out = {
            "step": self.step_count,
            "time": self.step_count * self.dt,
            "kinetic_energy": float(v[KE]),
            "max_penetration": float(v[MAX_PEN]),
            "mean_penetration": float(v[SUM_PEN] / n) if n else 0.0,
            "contacts": n,
            "manifolds": int(self.contacts.manifold_count[None]),
            "residual_rms": float(np.sqrt(v[RES_SQ_SUM] / (3 * n))) if n else 0.0,
            "residual_max": float(np.sqrt(v[RES_MAX_SQ])),
        }
        if self.solver == "pgs-colored":
            out["colors"] = int(getattr(self, "last_color_count", 0))
        return out

    def timing_ms(self) -> dict[str, float]:
        return self.profiler.mean_ms()
