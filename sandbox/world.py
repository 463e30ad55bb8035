"""World: owns the Taichi data of one scene and runs the step.

The step, stage by stage (names = profile keys = report keys):

1. ``broadphase``   AABBs, hash grid, candidate pairs (broadphase.py)
2. ``narrowphase``  manifolds into the contact buffer (contacts.py)
3. ``prepare``      rows, warm-start matching, schedule set-up (solvers/)
4. ``iterations`` substeps of h / iterations (Box2D v3's soft step, see solvers/rows.py):
   ``integrate_velocities`` (gravity), ``iterate`` (warm start + one biased sweep of the
   chosen schedule), ``integrate_positions`` (symplectic Euler, conservative rotation,
   finite guard), ``relax`` (one rigid sweep without position bias)
5. ``relax``        restitution pass, impulses stored for the next step

Python only orchestrates. With the profiler off, the once-per-step stages run in three
launches (``step_kernels.py``: state save + broadphase + narrowphase, then rows + matching +
schedule set-up, then velocity check + contact store; the same loops as the per-stage
kernels, the same bits). The iteration loop of step 4 is one kernel launch on
the CPU, shared by its threads (``Settings.iteration_launch``, solvers/substep.py and
team.py: launch and dispatch overhead, not arithmetic, bound small scenes) or one
launch per substep on CUDA; with
the profiler on it runs stage by stage, a launch per phase, so that each stage
has its timer (the unfused path; the iteration loop is then ``iterate`` plus the
per-phase stages). Besides the launches a step makes two small reads: buffer
counters after the narrowphase (a buffer that overflowed is grown and the step
redone from the saved state) and the error bits at the end (non-finite state:
the last good state is restored and a SimulationError names the body and the
stage). ``[world] substeps`` repeats the whole step, collision
included, with dt / substeps.

Fracture (``fracture.py``) replaces a body by its pieces through the same rebuild
as ``add_bodies`` / ``remove_bodies``: every other body keeps its state, and piece 0
takes the broken body's index, so the indices of the other bodies never change.
The other pieces of a scripted or API fracture are appended (before any impact
pieces); those of an impact fracture go at the very end, so the indices a scene's
timeline was resolved to at load time stay valid however bodies break on impact.
Breakable bodies (``strength``) are watched by ``impact.py`` only when the scene has
some; one that broke in a step is fractured at the start of the next step, before
that step's scripted events, and the fracture is logged like any event, so a replay
applies it from the log.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import taichi as ti

from . import backend
from .errors import CapacityError, SandboxError, SimulationError
from .fracture import FractureError, check_arguments, fracture_body, piece_count
from .scene.spec import EventSpec
from .profile import Profiler
from .scene.spec import Scene
from .settings import Settings
from .solvers import SOLVERS, check_solver

MAX_GROWTH_RETRIES = 6


class World:
    """A simulated scene. ``World(scene, solver=..., iterations=..., arch=...)``."""

    def __init__(self, scene: Scene, solver: str | None = None, iterations: int | None = None, arch: str = "auto",
                 settings: Settings | None = None, profile: bool = False, reserve_pieces: int = 0, **solver_options):
        """``reserve_pieces``: room for this many fracture pieces beyond what the scene's breakable
        bodies and fracture events need (those are reserved anyway), so that fractures neither grow
        the buffers nor bring a new shape kind, both of which recompile the kernels once."""
        if not isinstance(scene, Scene):
            raise SandboxError(f"World needs a Scene (Scene.load(path) or Scene.from_dict(d)), got {type(scene).__name__}")
        self.arch = backend.init(arch)
        self.scene = scene
        self.settings = settings or Settings()
        if scene.world.contact_hertz is not None and settings is None:
            self.settings = self.settings.replace(contact_hertz=float(scene.world.contact_hertz))
        self.dt = float(scene.world.dt)
        self.substeps = int(scene.world.substeps)
        self.gravity = np.asarray(scene.world.gravity, dtype=np.float32)
        self.profiler = Profiler(profile)
        self._fuse_step = True  # False: the once-per-step stages launch one by one (benchmarks compare)
        self.step_count = 0
        self.record_residuals = False
        """When True, ``residual_history`` holds the RMS LCP residual [m/s] after every biased
        sweep of the last step (one device read per sweep: for convergence plots, not speed)."""
        self.residual_history: list[float] = []
        from .build import host_world

        self._bodies = list(scene.bodies)  # the live body list (events add and remove)
        self._pending = sorted(scene.events, key=lambda e: e.time)  # stable: file order on ties
        self.applied_events: list[tuple[int, object]] = []
        """(step, EventSpec) of every event applied so far, scripted or interactive: what a
        recording stores so that a replay applies exactly the same edits."""
        self.auto_fracture = True
        """Breakable bodies fracture when a contact impulse exceeds their strength. A replay turns
        this off: the recorded log holds those fractures as events."""
        self.fracture_failures: list[str] = []
        """Impact fractures that could not happen, one sentence each (the body stayed whole and
        stopped being breakable)."""
        self.last_fracture: list = []
        """``fracture.FractureResult`` of each body of the last fracture (how exact its pieces were)."""
        self._tail = 0  # pieces of impact fractures at the end of the body list
        self._breaking: list[int] = []  # bodies that broke in the last step, fractured before the next
        if isinstance(reserve_pieces, bool) or not isinstance(reserve_pieces, (int, np.integer)) or reserve_pieces < 0:
            raise SandboxError(f"reserve_pieces must be an integer >= 0, got {reserve_pieces!r}")
        reserve = _fracture_reserve(scene) + int(reserve_pieces)
        self._host = host_world(scene, self.settings)
        from .shapes import HULL

        self.kinds = _union_kinds(self._host.kinds, (HULL,) if reserve else ())
        effects = tuple(getattr(scene, "effects", ("friction", "restitution")))
        self.friction = "friction" in effects  # compile-time: friction rows exist only if asked for
        self.restitution = "restitution" in effects
        self.body_count = len(scene.bodies)
        self._acquire(self._host.capacities(reserve_pieces=reserve))
        self._update_breakable()
        opts = dict(scene.solver.options)
        opts.update(solver_options)
        self.set_solver(solver or scene.solver.name, iterations=iterations or scene.solver.iterations, **opts)
        self.initial_solver = (self.solver, self.iterations, dict(self.solver_options))
        """The solver the world started with: a recording begun later re-simulates from step 0."""

    # ------------------------------------------------------------------ buffers
    def _acquire(self, caps) -> None:
        from . import buffers
        from .build import upload

        self.buf = buffers.acquire(caps)
        self._finalizer = buffers.release_on_collect(self, self.buf)
        upload(self._host, self.buf, self.settings.contact_margin)

    def close(self) -> None:
        """Give the device buffers back to the process pool (also done when collected)."""
        if getattr(self, "_finalizer", None) is not None:
            self._finalizer()
            self._finalizer = None

    # ------------------------------------------------------------------ solver
    def set_solver(self, name: str, iterations: int | None = None, **options) -> None:
        """Switch solver between steps; the world and its warm-start impulses are kept."""
        iterations = self.iterations if iterations is None else iterations
        self.solver_options = check_solver(name, iterations, options)
        self.solver = name
        self.iterations = iterations

    def set_gravity(self, gravity) -> None:
        """A new gravity vector [m/s^2], from the next step on."""
        self.gravity = _finite_vector(gravity, "gravity").astype(np.float32)

    def set_effects(self, effects) -> None:
        """Switch contact effects between steps ("friction", "restitution"); each combination
        compiles its own kernels on first use, so an effect that is off costs nothing."""
        from .scene.loader import EFFECTS

        effects = tuple(effects)
        unknown = [e for e in effects if e not in EFFECTS]
        if unknown:
            raise SandboxError(f"unknown effect(s) {unknown}; known: {list(EFFECTS)}")
        self.friction = "friction" in effects
        self.restitution = "restitution" in effects

    @property
    def effects(self) -> tuple:
        return tuple(e for e, on in (("friction", self.friction), ("restitution", self.restitution)) if on)

    def set_timestep(self, dt: float | None = None, substeps: int | None = None) -> None:
        """A new step [s] and/or number of substeps; the state and warm start are kept."""
        if dt is not None:
            if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating)) or not (0.0 < dt <= 1.0):
                raise SandboxError(f"dt must be a number of seconds in (0, 1], got {dt!r}")
            self.dt = float(dt)
        if substeps is not None:
            if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or not 1 <= substeps <= 1000:
                raise SandboxError(f"substeps must be an integer in 1..1000, got {substeps!r}")
            self.substeps = int(substeps)

    # ------------------------------------------------------------------ edits and events
    def apply_event(self, event) -> None:
        """Apply one timeline event now (between steps) and log it for recordings."""
        from .timeline import apply_event

        apply_event(self, event)
        self.applied_events.append((self.step_count, event))

    def add_bodies(self, bodies: list) -> list[int]:
        """Append bodies (BodySpecs) to the world; returns their indices. Body state is kept;
        warm-start impulses are dropped once (the contact buffer is rebuilt). They go before the
        pieces of impact fractures, if there are any (module docstring)."""
        self._flush_breaks()
        live = self._live_specs()
        self._check_body_budget(len(live) + len(bodies), "adding bodies")
        at = len(live) - self._tail
        self._rebuild(live[:at] + list(bodies) + live[at:])
        return list(range(at, at + len(bodies)))

    def remove_bodies(self, indices) -> None:
        """Remove bodies; the bodies after them move down to close the gaps."""
        drop = set(self._check_indices(indices, "remove"))
        self._flush_breaks()
        self._tail -= sum(1 for i in drop if i >= len(self._bodies) - self._tail)
        self._rebuild([b for i, b in enumerate(self._live_specs()) if i not in drop])

    def fracture(self, bodies, pieces: int = 8, seed: int = 0, impulse: float = 0.0, *, impact: bool = False) -> list[int]:
        """Break dynamic bodies into convex pieces (``fracture.py``); returns the pieces' indices.

        A compound breaks into its shapes, a convex body into ``pieces`` Voronoi cells seeded with
        ``seed`` (``seed + k`` for the k-th listed body). Each piece keeps the parent's velocity
        field, plus a share of the outward ``impulse`` [N s] (a total; it conserves momentum).
        Piece 0 takes the body's index; the others are appended, before the pieces of impact
        fractures, or after everything with ``impact=True`` (how impact fractures are applied).
        Every other body keeps its state. A static body, an unknown index, or a body that cannot
        be split (too small for ``Settings.fracture_min_piece_size``) raises SandboxError and leaves
        the world unchanged; more than ``Settings.max_bodies`` bodies raises CapacityError.
        """
        try:
            check_arguments(pieces, seed, impulse)
        except FractureError as exc:
            raise FractureError(f"fracture: {exc}") from None
        idx = self._check_indices(bodies, "fracture")
        if not idx:
            raise SandboxError("fracture: no body given")
        if len(set(idx)) != len(idx):
            raise SandboxError(f"fracture: a body is listed twice in {idx}")
        for i in idx:
            if self._bodies[i].static:
                raise SandboxError(f"fracture: body {i}{self.body_name(i)} is static and cannot be fractured")
        if not impact:
            self._flush_breaks()
        live = self._live_specs()
        results = []
        for k, i in enumerate(idx):
            try:
                results.append(fracture_body(live[i], pieces=pieces, seed=int(seed) + k,
                                             impulse=impulse, min_piece_size=self.settings.fracture_min_piece_size))
            except FractureError as exc:
                raise FractureError(f"fracture: body {i}{self.body_name(i)} stays whole: {exc}") from None
        extras = [piece for r in results for piece in r.bodies[1:]]
        self._check_body_budget(len(live) + len(extras), f"fracturing {len(idx)} body(ies) into {len(extras) + len(idx)} pieces")
        for i, r in zip(idx, results):
            live[i] = r.bodies[0]
        at = len(live) if impact else len(live) - self._tail
        self._rebuild(live[:at] + extras + live[at:])
        if impact:
            self._tail += len(extras)
        self.last_fracture = results
        out, next_index = [], at
        for i, r in zip(idx, results):
            out.append(i)
            out.extend(range(next_index, next_index + len(r.bodies) - 1))
            next_index += len(r.bodies) - 1
        return out

    def _check_body_budget(self, count: int, what: str) -> None:
        if count > self.settings.max_bodies:
            raise CapacityError(f"{what} would make {count} bodies; this world holds at most "
                                f"{self.settings.max_bodies} (Settings.max_bodies: raise it with "
                                "World(..., settings=Settings().replace(max_bodies=...)))")

    def _update_breakable(self) -> None:
        """Strength per body (inf: not breakable); the impact monitor runs only when one is finite."""
        self._strength = np.array([b.strength if b.breakable and not b.static else np.inf for b in self._bodies],
                                  dtype=np.float64)
        self._watch_impacts = bool(np.isfinite(self._strength).any())

    def impact_impulses(self) -> np.ndarray:
        """Largest total normal impulse [N s] one contact manifold passed to each body in the last
        step (impact.py); tracked only while the world has breakable bodies (else zeros)."""
        if not self._watch_impacts:
            return np.zeros(self.body_count)
        return self.buf.impacts.body_max.to_numpy()[: self.body_count].astype(np.float64)

    def _flush_breaks(self) -> None:
        """Fracture the bodies that broke in the last step, one logged event each. Runs at the start
        of the next step, or earlier when an edit changes the body list (impact pieces never move
        other bodies' indices, so the edit's indices stay valid)."""
        if not self._breaking:
            return
        broken, self._breaking = self._breaking, []
        for i in broken:
            body = self._bodies[i]
            event = EventSpec(time=self.step_count * self.dt, kind="fracture", bodies=[i], pieces=int(body.pieces),
                              seed=int(self.step_count), outward_impulse=0.0, cause="impact")
            try:
                self.apply_event(event)
            except FractureError as exc:
                self._bodies[i] = dataclasses.replace(body, breakable=False)
                self._update_breakable()
                self.fracture_failures.append(f"step {self.step_count}: {exc}; it is no longer breakable")

    def set_velocity(self, indices, linear=None, angular=None) -> None:
        """Set the linear [m/s] and/or angular [rad/s, world] velocity of dynamic bodies."""
        idx = self._check_indices(indices, "set_velocity", dynamic=True)
        b = self.buf.bodies
        for name, value in (("lin_vel", linear), ("ang_vel", angular)):
            if value is not None:
                v = _finite_vector(value, name)
                field = getattr(b, name)
                arr = field.to_numpy()
                arr[idx] = v
                field.from_numpy(arr)

    def apply_impulse(self, indices, impulse, point=None) -> None:
        """Apply a world-frame impulse [N s] at ``point`` (world, default the centre of mass)."""
        idx = self._check_indices(indices, "impulse", dynamic=True)
        j = _finite_vector(impulse, "impulse")
        b = self.buf.bodies
        v, w = b.lin_vel.to_numpy(), b.ang_vel.to_numpy()
        pos, rot, inv_i = b.pos.to_numpy(), b.rot.to_numpy(), b.inv_inertia.to_numpy()
        inv_m = b.inv_mass.to_numpy()
        for i in idx:
            v[i] += inv_m[i] * j
            if point is not None:
                from .build import _quat_mat

                r = _quat_mat(rot[i].astype(np.float64))
                arm = _finite_vector(point, "point") - pos[i]
                w[i] += (r @ inv_i[i] @ r.T) @ np.cross(arm, j)
        b.lin_vel.from_numpy(v)
        b.ang_vel.from_numpy(w)

    def _check_indices(self, indices, what: str, dynamic: bool = False) -> list[int]:
        idx = [indices] if isinstance(indices, (int, np.integer)) else list(indices)
        n = len(self._bodies)
        for i in idx:
            if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < n:
                raise SandboxError(f"{what}: no body {i!r} (the world has bodies 0..{n - 1})")
            if dynamic and self._bodies[i].static:
                raise SandboxError(f"{what}: body {i}{self.body_name(i)} is static and cannot be moved")
        return [int(i) for i in idx]

    def _live_specs(self) -> list:
        """The current body list with positions and velocities read back from the device."""
        import dataclasses

        st = self.buf.bodies.host_state()
        return [dataclasses.replace(b, position=st["pos"][i], orientation=st["rot"][i],
                                    linear_velocity=st["lin_vel"][i], angular_velocity=st["ang_vel"][i])
                for i, b in enumerate(self._bodies)]

    def _rebuild(self, bodies: list) -> None:
        from .build import host_world, upload

        self._bodies = bodies
        self._host = host_world(dataclasses.replace(self.scene, bodies=bodies), self.settings)
        self.kinds = _union_kinds(self.kinds, self._host.kinds)  # a kind once compiled stays: no recompile back
        self.body_count = len(bodies)
        old = self.buf.caps
        caps = self._host.capacities(pairs=old.pairs, grid_entries=old.grid_entries).covering(old)
        if caps == old:
            upload(self._host, self.buf, self.settings.contact_margin)
        else:
            self.close()
            self._acquire(caps)
        self._update_breakable()

    # ------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise SandboxError(f"step count must be a non-negative integer, got {n!r}")
        h = self.dt / self.substeps
        self._h = h
        for _ in range(int(n)):
            self._flush_breaks()
            while self._pending and int(round(self._pending[0].time / self.dt)) <= self.step_count:
                self.apply_event(self._pending.pop(0))
            watch = self._watch_impacts and self.auto_fracture
            for s in range(self.substeps):
                self._substep(h, watch, first=s == 0)
            if watch:
                peak = self.buf.impacts.body_max.to_numpy()[: self.body_count]
                self._breaking = [int(i) for i in np.flatnonzero(peak > self._strength)]
            self.step_count += 1
            self.profiler.steps += 1

    def _substep(self, h: float, watch: bool = False, first: bool = True) -> None:
        from .bodies import restore_good_state, save_good_state, update_world_inertia
        from .integrate import check_velocities, integrate_positions, integrate_velocities
        from .persistence import match_contacts, store_contacts
        from .solvers import substep
        from .solvers.rows import BIASED, RELAX, RESTITUTION, prepare_rows, soft_contact_coefficients

        b, s, p = self.buf, self.settings, self.profiler
        k = self.iterations
        h_sub = h / k
        gravity = ti.math.vec3(*self.gravity)
        fused = self._fuse_step and not p.enabled  # the once-per-step stages in three launches (step_kernels.py)
        if not fused:
            save_good_state(b.bodies)
            b.errors.clear()
            update_world_inertia(b.bodies)
        self.residual_history = []
        for attempt in range(MAX_GROWTH_RETRIES + 1):
            if fused:  # a retry saves the restored (same) state again and redoes the inertias: same bits
                self._begin_and_collide()
            else:
                self._collide()
            if not self._grow_if_needed():
                break
            b = self.buf
        else:
            raise CapacityError("contact buffers kept overflowing after growing; the scene is too dense")
        if watch:
            from .impact import clear_bodies, clear_points

            if first:
                clear_bodies(b.impacts, b.bodies)
            clear_points(b.impacts, b.contacts)
        with p.stage("prepare"):
            bias_rate, softness = soft_contact_coefficients(h_sub, s.contact_hertz, s.contact_damping_ratio)
            if fused:
                from .step_kernels import prepare_step

                kind, blk, mode, omega, split = self._schedule_setup()
                prepare_step(b.rows, b.contacts, b.bodies, b.history, blk, 1.0 / h_sub, bias_rate, softness,
                             s.max_push_speed, s.restitution_threshold, s.match_distance, s.warm_start / k, kind,
                             mode, omega, split)
                self._prepare_coloring()
            else:
                prepare_rows(b.rows, b.contacts, b.bodies, 1.0 / h_sub, bias_rate, softness, s.max_push_speed,
                             s.restitution_threshold)
                match_contacts(b.history, b.contacts, b.rows, s.match_distance, s.warm_start / k)
                self._prepare_schedule()
        launch = self._iteration_launch()
        warm = s.warm_start > 0.0
        fold = substep.folds_warm_start(self._visit(), warm)
        if launch == "one":
            kind, blk, rows, c, bodies = self._schedule()
            with p.stage("iterate"):
                substep.iterate_in_order(blk, rows, c, bodies, b.coloring, b.errors, kind, self._visit(),
                                         self.friction, warm, b.impacts, watch, gravity, h_sub, k, s.sweeps)
        elif launch == "shared":
            from .solvers import team

            kind, blk, rows, c, bodies = self._schedule()
            phases = substep.shared_phase_bound(self._visit(), k, s.sweeps)
            members = team.cpu_threads()
            with p.stage("iterate"):
                substep.iterate_shared(team.team_for(phases, members), blk, rows, c, bodies, b.coloring, b.errors,
                                       kind, self._visit(), self.friction, warm, b.impacts, watch, gravity, h_sub, k,
                                       s.sweeps, phases, members)
        elif launch == "per-substep":
            kind, blk, rows, c, bodies = self._schedule()
            with p.stage("iterate"):
                for i in range(k):
                    warm_here, then_warm = int(i == 0 or not fold), int(fold and i < k - 1)
                    substep.substep_parallel(blk, rows, c, bodies, b.coloring, b.errors, kind, self._visit(),
                                             self.friction, warm, b.impacts, watch, gravity, h_sub, warm_here,
                                             then_warm)
        else:
            # stage by stage; with warm starting, gravity rides on the warm-start pass ("iterate"),
            # and for the Jacobi family both ride on the previous substep's last relax sweep
            for i in range(k):
                if i == 0 or not fold:
                    if warm:
                        with p.stage("iterate"):
                            self._warm_start(gravity, h_sub)
                    else:
                        with p.stage("integrate_velocities"):
                            integrate_velocities(b.bodies, gravity, h_sub)
                with p.stage("iterate"):
                    for _ in range(s.sweeps):
                        self._sweep(BIASED)
                        if self.record_residuals:
                            self.residual_history.append(self._residual_rms())
                with p.stage("integrate_positions"):
                    integrate_positions(b.bodies, h_sub, b.errors)
                with p.stage("relax"):
                    for j in range(s.sweeps):
                        self._sweep(RELAX, int(fold and i < k - 1 and j == s.sweeps - 1), gravity, h_sub)
                if watch:
                    from .impact import accumulate_points

                    accumulate_points(b.impacts, b.contacts, b.rows)
        if watch:
            from .impact import reduce_manifolds

            reduce_manifolds(b.impacts, b.contacts)
        with p.stage("relax"):
            if self.restitution and self._host.has_restitution:
                self._sweep(RESTITUTION)
            if fused:
                from .step_kernels import finish_step

                finish_step(b.history, b.contacts, b.rows, b.bodies, b.shapes, b.errors, k)
            else:
                check_velocities(b.bodies, b.errors)
                store_contacts(b.history, b.contacts, b.rows, b.shapes, k)
        flags = int(b.errors.flags[None])
        if flags:
            from .broadphase import MAX_SPAN_CELLS
            from .manifold_cache import clear_cache
            from .persistence import clear_history

            from .integrate import ERR_POSE, ERR_VELOCITY

            body = int(b.errors.body[None])
            name = self.body_name(body)
            if flags & (ERR_VELOCITY | ERR_POSE):
                stage = "solve (velocity)" if flags & ERR_VELOCITY else "integrate_positions (pose)"
                problem = f"non-finite {stage} of body {body}{name}"
            else:
                v = float(np.linalg.norm(b.bodies.lin_vel[body]))
                w = float(np.linalg.norm(b.bodies.ang_vel[body]))
                problem = (f"body {body}{name} reached |v| = {v:.3g} m/s, |w| = {w:.3g} rad/s: its bounds over the "
                           f"step cover more than {MAX_SPAN_CELLS} broadphase cells of {b.bp.cell_size[None]:.3g} m "
                           "(the solver diverged, or the body is far larger than the typical one)")
            restore_good_state(b.bodies)
            clear_history(b.history)  # this step's impulses are not usable either: no warm start from them
            clear_cache(b.manifold_cache)  # nor its manifolds (a replay from the good state would not have them)
            raise SimulationError(f"step {self.step_count}: {problem}; the world was restored to its last good state")

    def _collide(self) -> None:
        from .broadphase import build_dynamic_grid, find_pairs
        from .contacts import collide_pairs

        b, p, margin = self.buf, self.profiler, self.settings.contact_margin
        with p.stage("broadphase"):
            build_dynamic_grid(b.bp, b.shapes, b.bodies, margin, self._h, b.errors)
            find_pairs(b.bp, b.shapes)
        with p.stage("narrowphase"):
            collide_pairs(b.contacts, b.bp, b.shapes, b.bodies, b.pool, b.manifold_cache, margin, self.settings.slop,
                          self._h, *self.settings.manifold_reuse_bounds(), self.kinds)

    def _begin_and_collide(self) -> None:
        from .step_kernels import begin_and_collide

        b, st = self.buf, self.settings
        begin_and_collide(b.bodies, b.errors, b.bp, b.shapes, b.contacts, b.pool, b.manifold_cache, st.contact_margin,
                          st.slop, self._h, *st.manifold_reuse_bounds(), self.kinds)

    def _grow_if_needed(self) -> bool:
        """After an overflow: move to a bigger buffer class, keeping the body state, and say so."""
        from .bodies import restore_good_state

        b = self.buf
        entries = int(b.bp.entry_total[None])
        pairs = int(b.bp.pair_total[None])
        if entries <= b.bp.entry_capacity and pairs <= b.bp.pair_capacity:
            return False
        restore_good_state(b.bodies)
        n = len(self._host.body_arrays["inv_mass"])
        for k, v in b.bodies.host_state().items():
            self._host.body_arrays[k] = v[:n]
        caps = b.caps.grown(grid_entries=max(b.caps.grid_entries, 2 * entries), pairs=max(b.caps.pairs, 2 * pairs))
        self.close()
        self._acquire(caps)
        return True

    def _iteration_launch(self) -> str:
        """"shared", "one", "per-substep" or "per-stage" (Settings.iteration_launch,
        solvers/substep.py). All give bit-identical results."""
        if self.profiler.enabled or self.record_residuals:
            return "per-stage"  # a timer per stage, a residual read per sweep
        launch = self.settings.iteration_launch
        if launch == "auto":
            launch = "shared" if self.arch == "cpu" else "per-substep"
        if launch == "shared" and (self.arch != "cpu" or self.solver == "pgs"):
            return "one"  # a GPU block cannot wait for another; serial PGS has nothing to share
        if launch == "per-substep" and (self.solver == "pgs-colored" or self.settings.sweeps != 1):
            return "per-stage"  # launches per colour; a sweep count is not unrolled into the kernel
        return launch

    def _visit(self) -> int:
        from .solvers import substep

        return {"pgs": substep.PGS, "pgs-colored": substep.PGS_COLORED}.get(self.solver, substep.BLOCKS)

    def _schedule(self):
        from .solvers import mass_splitting as blocks

        kind = blocks.PER_POINT if SOLVERS[self.solver].block == "point" else blocks.PER_MANIFOLD
        return kind, self.buf.blocks, self.buf.rows, self.buf.contacts, self.buf.bodies

    def _schedule_setup(self):
        """(kind, block scratch, adjacency mode, omega, split responses) of the chosen schedule."""
        from .solvers import mass_splitting as blocks

        kind, b, rows, c, bodies = self._schedule()
        split = self.solver in ("mass-splitting", "block-mass-splitting")
        omega = self.solver_options.get("relaxation") or (1.0 if split else self.settings.jacobi_relaxation)
        return (kind, b, blocks.MODE_SPLIT if split else blocks.MODE_JACOBI, float(omega),
                not self.solver.startswith("pgs"))

    def _prepare_schedule(self) -> None:
        """Per-step set-up of the chosen schedule: body adjacency (all), colouring (pgs-colored)."""
        from .solvers import mass_splitting as blocks
        from .solvers.rows import prepare_response

        kind, b, mode, omega, split = self._schedule_setup()
        _, _, rows, c, bodies = self._schedule()
        blocks.build_adjacency(b, c, bodies, kind, mode, omega)
        prepare_response(rows, c, bodies, b.scale, split)
        self._prepare_coloring()

    def _prepare_coloring(self) -> None:
        from .solvers import pgs

        c, bodies = self.buf.contacts, self.buf.bodies
        if self.solver == "pgs-colored":
            o = self.solver_options
            col = self.buf.coloring
            pgs.color_manifolds(col, c, bodies, int(o["shuffle"]), int(o["seed"]), self.step_count)
        self._color_starts = None  # read from the device by the first host-driven sweep that needs them

    def _warm_start(self, gravity, h: float) -> None:
        from .solvers import mass_splitting as blocks

        kind, b, rows, c, bodies = self._schedule()
        blocks.warm_start(b, rows, c, bodies, kind, gravity, h)

    def _sweep(self, mode: int, then_warm: int = 0, gravity=None, h: float = 0.0) -> None:
        """One pass of the chosen schedule over every contact row (``then_warm``: blocks.sweep_blocks)."""
        from .solvers import mass_splitting as blocks, pgs

        kind, b, rows, c, bodies = self._schedule()
        fr = self.friction
        if self.solver == "pgs":
            pgs.pgs_serial(rows, c, bodies, mode, fr)
        elif self.solver == "pgs-colored":
            col, overflow = self.buf.coloring, pgs.MAX_COLORS
            if self._color_starts is None:  # one launch per colour: the ranges come to the host once a step
                self._color_starts = pgs.color_ranges(col)
                self._color_count = int(col.color_count[None])
            starts = self._color_starts
            for k in range(self._color_count):
                pgs.solve_color(rows, c, bodies, col, int(starts[k]), int(starts[k + 1]), mode, fr)
            if starts[overflow + 1] > starts[overflow]:
                pgs.solve_overflow(rows, c, bodies, col, int(starts[overflow]), int(starts[overflow + 1]), mode, fr)
        else:
            g = gravity if gravity is not None else ti.math.vec3(0.0)
            blocks.jacobi_sweep(b, rows, c, bodies, kind, mode, fr, then_warm, g, h)

    # ------------------------------------------------------------------ queries
    def body_name(self, i: int) -> str:
        if 0 <= i < len(self._bodies) and self._bodies[i].name:
            return f" ({self._bodies[i].name!r})"
        return ""

    @property
    def body_specs(self) -> tuple:
        """Each body's description (shapes, mass, material, name) in index order. Positions
        and velocities in it are those the body was added with; ``state()`` has the live ones."""
        return tuple(self._bodies)

    def state(self, fields=None) -> dict[str, np.ndarray]:
        """Body state as numpy arrays, one row per scene body: position (N,3) [m, centre of
        mass], orientation (N,4) [w, x, y, z], linear_velocity (N,3) [m/s], angular_velocity
        (N,3) [rad/s, world frame]. ``fields``: only these keys (fewer device copies)."""
        st = self.buf.bodies.state_numpy(fields)
        return {k: v[: self.body_count].copy() for k, v in st.items()}

    def metrics(self) -> dict[str, float]:
        from .metrics import KE, MAX_PEN, RES_MAX_SQ, RES_SQ_SUM, SUM_PEN, compute_metrics
        from .solvers.rows import RELAX, compute_residuals

        b = self.buf
        compute_residuals(b.rows, b.contacts, b.bodies, RELAX)  # the step ends with the rigid relax
        compute_metrics(b.metrics, b.bodies, b.contacts, b.rows)
        v = b.metrics.values.to_numpy().astype(np.float64)
        n = int(b.contacts.count[None])
        out = {
            "step": self.step_count,
            "time": self.step_count * self.dt,
            "kinetic_energy": float(v[KE]),
            "max_penetration": float(v[MAX_PEN]),
            "mean_penetration": float(v[SUM_PEN] / n) if n else 0.0,
            "contacts": n,
            "manifolds": int(b.contacts.manifold_count[None]),
            "manifolds_reused": int(b.manifold_cache.reused[None]),
            "pairs": int(min(b.bp.pair_total[None], b.bp.pair_capacity)),
            "pairs_reused": int(b.manifold_cache.reused_pairs[None]),
            "residual_rms": float(np.sqrt(v[RES_SQ_SUM] / (3 * n))) if n else 0.0,
            "residual_max": float(np.sqrt(v[RES_MAX_SQ])),
        }
        if self.solver == "pgs-colored":
            out["colors"] = self.last_color_count
        return out

    @property
    def last_color_count(self) -> int:
        """Colours pgs-colored used in the last step (read from the device)."""
        return int(self.buf.coloring.color_count[None]) if self.solver == "pgs-colored" else 0

    def _residual_rms(self) -> float:
        """RMS residual of the biased problem the sweeps are solving right now."""
        from .metrics import RES_SQ_SUM, compute_metrics
        from .solvers.rows import BIASED, compute_residuals

        b = self.buf
        compute_residuals(b.rows, b.contacts, b.bodies, BIASED)
        compute_metrics(b.metrics, b.bodies, b.contacts, b.rows)
        n = int(b.contacts.count[None])
        return float(np.sqrt(b.metrics.values[RES_SQ_SUM] / (3 * n))) if n else 0.0

    def contacts(self, fields=None) -> dict[str, np.ndarray]:
        """This step's contact points: body_a, body_b, point (world) [m], normal (a to b),
        separation at the step start [m], impulse over the step (normal, tangent1, tangent2)
        [N s] and manifold index. ``fields``: only these keys (fewer device copies)."""
        c, r = self.buf.contacts, self.buf.rows
        n = int(c.count[None])
        read = {
            "body_a": lambda: c.body_a.to_numpy()[:n],
            "body_b": lambda: c.body_b.to_numpy()[:n],
            "point": lambda: c.point.to_numpy()[:n],
            "normal": lambda: c.normal.to_numpy()[:n],
            "separation": lambda: c.sep.to_numpy()[:n],
            "impulse": lambda: r.lam.to_numpy()[:n] * self.iterations,  # per substep -> per step
            "manifold": lambda: c.manifold.to_numpy()[:n],
        }
        return {k: read[k]() for k in (fields or read)}

    def timing_ms(self) -> dict[str, float]:
        return self.profiler.mean_ms()


def _union_kinds(a, b) -> tuple:
    return tuple(sorted(set(a) | set(b)))


def _fracture_reserve(scene: Scene) -> int:
    """Pieces the scene may create: every breakable body's, and every fracture event's."""
    bodies = scene.bodies
    total = sum(piece_count(b, b.pieces) for b in bodies if b.breakable and not b.static)
    for event in scene.events:
        if event.kind == "fracture":
            total += sum(piece_count(bodies[i], event.pieces) if i < len(bodies) else event.pieces
                         for i in event.bodies)
    return total


def _finite_vector(value, what: str) -> np.ndarray:
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raw = np.asarray(None)
    has_bool = isinstance(value, (list, tuple)) and any(isinstance(x, (bool, np.bool_)) for x in value)
    if raw.shape != (3,) or raw.dtype.kind not in "iuf" or has_bool:
        raise SandboxError(f"{what} must be three numbers, got {value!r}")
    v = raw.astype(np.float64)
    if not np.all(np.isfinite(v)):
        raise SandboxError(f"{what} must be finite, got {value!r}")
    return v
