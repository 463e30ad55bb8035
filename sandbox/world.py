"""World: one simulated scene, the facade over the engine's parts.

A world holds its contents and their edits (``edits.py``: body list, host arrays, device
buffers), runs the step as a named list of stages (``step.py``), and steps with the
schedule of the chosen solver (``solvers/schedule.py``, built from the solver's
description in ``solvers/__init__.py``). Scripted and interactive events become calls of
its public methods (``timeline.py``) and are logged, so a recording replays the same edits.
"""

from __future__ import annotations

import numpy as np

from . import backend
from .edits import Edits, finite_vector
from .effects import CompiledEffects, compile_effects
from .errors import SandboxError
from .fracture import FractureError
from .profile import Profiler
from .scene.spec import Scene
from .settings import Settings
from .solvers import check_solver
from .solvers.schedule import Schedule
from .step import Controls, Stepper
from .timeline import edit_call


class World:
    """A simulated scene. ``World(scene, solver=..., iterations=..., arch=...)``."""

    def __init__(self, scene: Scene, solver: str | None = None, iterations: int | None = None, arch: str = "auto",
                 settings: Settings | None = None, profile: bool = False, reserve_pieces: int = 0,
                 reserve_kinds: tuple = (), formulation: str | None = None, **solver_options):
        """``reserve_pieces``: room for this many fracture pieces (or other added bodies) beyond what
        the scene's breakable bodies and fracture events need (those are reserved anyway), so that
        fractures neither grow the buffers nor bring a new shape kind, both of which recompile the
        kernels once. ``reserve_kinds``: shape kinds ("sphere", "capsule", "box", "hull") that bodies
        added later may have: the collision kernels are compiled for them from the first step, and
        the gyroscopic step too unless only spheres are named, so that adding such a body compiles
        nothing (the web sandbox's debris). It can change bits (a cube scene then turns its cubes
        with the gyroscopic solve), so recordings store it.
        ``formulation``: "soft-step" or "paper" (formulation.py), over the scene's and ``settings``'."""
        if not isinstance(scene, Scene):
            raise SandboxError(f"World needs a Scene (Scene.load(path) or Scene.from_dict(d)), got {type(scene).__name__}")
        if settings is not None and not isinstance(settings, Settings):
            raise SandboxError(f"settings must be a sandbox.Settings (e.g. Settings(sweeps=2), or "
                               f"Settings().replace(**changes)), got {type(settings).__name__}")
        self.arch = backend.init(arch)
        self.scene = scene
        settings_given = settings is not None
        settings = settings or Settings()
        if not settings_given:  # the scene's own settings, where it gives any
            settings = settings.replace(**scene.world.settings_given())
        if formulation is not None:
            settings = settings.replace(formulation=formulation)
        self.dt = float(scene.world.dt)
        self.substeps = int(scene.world.substeps)
        self.gravity = np.asarray(scene.world.gravity, dtype=np.float32)
        self.profiler = Profiler(profile)
        self.step_count = 0
        self.track_impulses = False
        """When True, every step sums its substeps' impulses (one more pass over the contacts per
        substep), which ``contacts()["impulse"]`` reports. Restitution and breakable bodies sum
        them anyway."""
        self.record_residuals = False
        """When True, ``residual_history`` holds the RMS LCP residual [m/s] after every biased
        sweep of the last step (one device read per sweep: for convergence plots, not speed)."""
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
        self._edits = Edits(scene, settings, reserve_pieces, tuple(reserve_kinds))
        self._inspection = None  # the step being inspected (inspect_step), if any
        self.reserve = (int(reserve_pieces), self._edits.reserve_kinds)
        """(reserve_pieces, reserve_kinds) as given: a recording stores them, since the compiled
        effects (and so the bits) can depend on them."""
        self.initial_settings = settings
        """The settings the world started with (formulation events change them; a recording
        begun later re-simulates from step 0 with these and the logged events)."""
        self._stepper = Stepper(self._edits, self.profiler)
        effects = tuple(getattr(scene, "effects", ("friction", "restitution")))
        self.friction = "friction" in effects  # compile-time: friction rows exist only if asked for
        self.restitution = "restitution" in effects
        self.sleeping = False  # resting islands sleep (sleep.py); switched on below, once the solver is set
        opts = dict(scene.solver.options)
        opts.update(solver_options)
        # None means "the scene's"; anything else is checked (0 iterations or an empty name is an error,
        # not the scene's default)
        self.set_solver(scene.solver.name if solver is None else solver,
                        iterations=scene.solver.iterations if iterations is None else iterations, **opts)
        self._set_sleeping("sleeping" in effects)
        self.initial_solver = (self.solver, self.iterations, dict(self.solver_options))
        """The solver the world started with: a recording begun later re-simulates from step 0."""

    def close(self) -> None:
        """Give the device buffers back to the process pool (also done when collected)."""
        if getattr(self, "_edits", None) is not None:
            self._edits.close()

    # ------------------------------------------------------------------ what the step reads
    @property
    def settings(self) -> Settings:
        return self._edits.settings

    @settings.setter
    def settings(self, value: Settings) -> None:
        self._edits.settings = value

    @property
    def buf(self):
        """The device buffers (buffers.BufferSet); replaced when they grow or a rebuild needs more."""
        return self._edits.buf

    @property
    def body_count(self) -> int:
        return self._edits.body_count

    @property
    def last_fracture(self) -> list:
        """``fracture.FractureResult`` of each body of the last fracture (how exact its pieces were)."""
        return self._edits.last_fracture

    @property
    def residual_history(self) -> list[float]:
        return self._stepper.residual_history

    # ------------------------------------------------------------------ solver and world settings
    def set_solver(self, name: str, iterations: int | None = None, **options) -> None:
        """Switch solver between steps; the world and its warm-start impulses are kept (every
        sleeping island wakes: the new solver may not hold it where the old one did)."""
        iterations = self.iterations if iterations is None else iterations
        self.solver_options = check_solver(name, iterations, options)
        self.solver = name
        self.iterations = iterations
        self._schedule = Schedule(name, self.solver_options)
        self.wake()

    @property
    def formulation(self) -> str:
        """The time-stepping scheme: "soft-step" or "paper" (Settings.formulation, formulation.py)."""
        return self.settings.formulation

    def set_formulation(self, name: str, baumgarte: float | None = None) -> None:
        """Switch the time-stepping scheme between steps ("soft-step" or "paper", and the paper's
        Baumgarte factor); state and warm-start impulses are kept (both store a step's impulse),
        every sleeping island wakes."""
        changes = {"formulation": name} if baumgarte is None else {"formulation": name, "baumgarte": baumgarte}
        self.settings = self.settings.replace(**changes)
        self.wake()

    def set_gravity(self, gravity) -> None:
        """A new gravity vector [m/s^2], from the next step on (every sleeping island wakes)."""
        self.gravity = finite_vector(gravity, "gravity").astype(np.float32)
        self.wake()

    def set_effects(self, effects) -> None:
        """Switch effects between steps ("friction", "restitution", "sleeping"); each combination
        compiles its own kernels on first use, so an effect that is off costs nothing. A change
        of the contact effects wakes every sleeping island; sleeping off wakes them too, and a
        world that has slept keeps its awake lists then (sleep.stop: the toggle compiles nothing,
        the bits are a never-sleeping world's; the lists' cost is in docs/sleeping.md)."""
        from .scene.loader import EFFECTS

        effects = tuple(effects)
        unknown = [e for e in effects if e not in EFFECTS]
        if unknown:
            raise SandboxError(f"unknown effect(s) {unknown}; known: {list(EFFECTS)}")
        friction, restitution = "friction" in effects, "restitution" in effects
        if (friction, restitution) != (self.friction, self.restitution):
            self.wake()
        self.friction, self.restitution = friction, restitution
        self._set_sleeping("sleeping" in effects)

    def _set_sleeping(self, on: bool) -> None:
        self._edits.set_sleeping(on)
        self.sleeping = bool(on)

    @property
    def compiled_effects(self) -> CompiledEffects:
        """The effects the step's kernels are compiled with now: those asked for that some body
        can use, and those the bodies call for (effects.py)."""
        edits = self._edits
        return compile_effects(self.effects, edits.host, self.settings, edits.anisotropic_reserved,
                               edits.spread_reserved)

    @property
    def effects(self) -> tuple:
        flags = (("friction", self.friction), ("restitution", self.restitution), ("sleeping", self.sleeping))
        return tuple(e for e, on in flags if on)

    def wake(self, bodies=None) -> None:
        """Wake the islands of ``bodies`` (indices), or every sleeping island (None). Nothing to
        do without the sleeping effect. Edits wake what they touch by themselves."""
        if bodies is not None:
            bodies = self._edits.check_indices(bodies, "wake")
        self._edits.wake(bodies)

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
        self.wake()

    # ------------------------------------------------------------------ edits and events
    def apply_event(self, event) -> None:
        """Apply one timeline event now (between steps) and log it for recordings."""
        call = edit_call(event, self.solver, self.solver_options)
        getattr(self, call.method)(*call.args, **call.kwargs)
        self.applied_events.append((self.step_count, event))

    def add_bodies(self, bodies: list) -> list[int]:
        """Append bodies (BodySpecs) to the world; returns their indices. The other bodies keep
        their state, their contacts' warm-start impulses and their support loads across the
        rebuild of the buffers (edits.py), so a resting pile does not notice. They go before the
        pieces of impact fractures, if there are any (edits.py)."""
        self._flush_breaks()
        return self._edits.add(bodies)

    def prepare_edits(self) -> None:
        """Compile now the kernels that adding or removing bodies launches (the body list's
        rebuild, upload and sleeping-island restore), and with sleeping on those of an island
        falling asleep and waking, instead of when they first happen. Changes no bit of the
        world; the web sandbox calls it while a world loads, so that the first "Drop debris" or
        the first island at rest does not pause the running world to compile."""
        self._edits.add([])
        self._edits.precompile_sleeping()

    def remove_bodies(self, indices) -> None:
        """Remove bodies; the bodies after them move down to close the gaps."""
        idx = self._edits.check_indices(indices, "remove")
        self._flush_breaks()
        self._edits.remove(idx)

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
        idx = self._edits.check_fracture(bodies, pieces, seed, impulse)
        if not impact:
            self._flush_breaks()
        return self._edits.fracture(idx, pieces, seed, impulse, impact)

    def set_velocity(self, indices, linear=None, angular=None) -> None:
        """Set the linear [m/s] and/or angular [rad/s, world] velocity of dynamic bodies."""
        self._edits.set_velocity(self._edits.check_indices(indices, "set_velocity", dynamic=True), linear, angular)

    def apply_impulse(self, indices, impulse, point=None) -> None:
        """Apply a world-frame impulse [N s] at ``point`` (world, default the centre of mass)."""
        self._edits.apply_impulse(self._edits.check_indices(indices, "impulse", dynamic=True), impulse, point)

    def impact_impulses(self) -> np.ndarray:
        """Largest total normal impulse [N s] one contact manifold passed to each body in the last
        step (impact.py); tracked only while the world has breakable bodies (else zeros)."""
        return self._edits.impact_impulses()

    def _flush_breaks(self) -> None:
        """Fracture the bodies that broke in the last step, one logged event each. Runs at the start
        of the next step, or earlier when an edit changes the body list (impact pieces never move
        other bodies' indices, so the edit's indices stay valid)."""
        for event in self._edits.take_breaks(self.step_count, self.dt):
            try:
                self.apply_event(event)
            except FractureError as exc:
                self._edits.keep_whole(event.bodies[0])
                self.fracture_failures.append(f"step {self.step_count}: {exc}; it is no longer breakable")

    def _live_specs(self) -> list:
        """The current body list with positions and velocities read back from the device."""
        return self._edits.live_specs()

    # ------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> None:
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise SandboxError(f"step count must be a non-negative integer, got {n!r}")
        if self._inspection is not None:
            raise SandboxError("a step is being inspected (World.inspect_step): finish it first")
        for _ in range(int(n)):
            for _ in self._one_step(pause=False):
                pass

    def inspect_step(self):
        """The next step, one sweep at a time: an ``inspection.StepInspection`` (advance, look at
        the contacts' impulses and residuals and a body's sub-body velocities, finish). Ends in
        the same state as ``step(1)``, bit for bit."""
        from .inspection import StepInspection

        if self._inspection is not None:
            raise SandboxError("a step is already being inspected: finish it first")
        self._inspection = StepInspection(self, self._one_step(pause=True))
        return self._inspection

    def _one_step(self, pause: bool):
        """One step (events due, every ``[world] substeps`` pass, breakage); a generator that
        yields a step.Sweep after every sweep when ``pause``, nothing otherwise."""
        h = self.dt / self.substeps
        self._flush_breaks()
        while self._pending and int(round(self._pending[0].time / self.dt)) <= self.step_count:
            self.apply_event(self._pending.pop(0))
        watch = self._edits.watch_impacts and self.auto_fracture
        controls = Controls(self._schedule, self.iterations, self.gravity, self.compiled_effects,
                            self.track_impulses, self.record_residuals, backend.loop_arch())
        for s in range(self.substeps):
            yield from self._stepper.substep_sweeps(controls, h, watch, first=s == 0, step_count=self.step_count,
                                                    pause=pause)
        if watch:
            self._edits.note_breaks()
        self.step_count += 1
        self.profiler.steps += 1

    # ------------------------------------------------------------------ queries
    def body_name(self, i: int) -> str:
        return self._edits.body_name(i)

    @property
    def body_specs(self) -> tuple:
        """Each body's description (shapes, mass, material, name) in index order. Positions
        and velocities in it are those the body was added with; ``state()`` has the live ones."""
        return tuple(self._edits.bodies)

    def state(self, fields=None) -> dict[str, np.ndarray]:
        """Body state as numpy arrays, one row per scene body: position (N,3) [m, centre of
        mass], orientation (N,4) [w, x, y, z], linear_velocity (N,3) [m/s], angular_velocity
        (N,3) [rad/s, world frame]. ``fields``: only these keys (fewer device copies)."""
        st = self.buf.bodies.state_numpy(fields)
        return {k: v[: self.body_count].copy() for k, v in st.items()}

    def metrics(self) -> dict[str, float]:
        """Energy [J], penetration [m], contact counts and the LCP residual [m/s] after the last
        step (metrics.py); awake and sleeping bodies and islands (islands.py, sleep.py);
        ``colors`` too when the solver colours its manifolds."""
        from .metrics import read_metrics, read_sleep_metrics
        from .solvers.rows import RELAX, compute_residuals

        b = self.buf
        # a step ends with the rigid relax; a step paused inside is solving its last sweep's problem
        mode = RELAX if self._inspection is None else self._inspection.mode
        compute_residuals(b.rows, b.contacts, b.bodies, mode)
        out = {"step": self.step_count, "time": self.step_count * self.dt, **read_metrics(b),
               **read_sleep_metrics(b, self.sleeping, self._edits.dynamic_count, self._edits.awake_set(self.sleeping))}
        colors = self._schedule.color_count(self.buf)
        if colors is not None:
            out["colors"] = colors
        return out

    def asleep(self) -> np.ndarray:
        """(N,) bool: which bodies sleep now (all False without the sleeping effect)."""
        from .sleep import asleep_mask

        if not self.sleeping:
            return np.zeros(self.body_count, dtype=bool)
        return asleep_mask(self.buf, self.body_count)

    def island_labels(self) -> np.ndarray:
        """(N,) int: each dynamic body's island as the smallest body index in it, -1 for static
        bodies (islands.py). Awake bodies' islands are those of the last step's contacts."""
        from .metrics import island_labels

        static = np.array([b.static for b in self._edits.bodies], dtype=bool)
        return island_labels(self.buf, self.sleeping, self.body_count, static, self._edits.awake_set(self.sleeping))

    @property
    def last_color_count(self) -> int:
        """Colours the solver used in the last step (read from the device; 0 when it does not colour)."""
        return self._schedule.color_count(self.buf) or 0

    def contacts(self, fields=None) -> dict[str, np.ndarray]:
        """This step's contact points: body_a, body_b, point (world) [m], normal (a to b),
        separation at the step start [m], impulse over the step (normal, tangent1, tangent2)
        [N s; the sum of the substeps' impulses, available after a step with
        ``track_impulses`` on], manifold index, and overlap (1: a placed overlap, pushed out no
        faster than ``Settings.overlap_push_speed``). ``fields``: only these keys (fewer device
        copies); without ``fields`` the impulse is left out unless it is tracked."""
        c, r = self.buf.contacts, self.buf.rows
        n = int(c.count[None])
        read = {
            "body_a": lambda: c.body_a.to_numpy()[:n],
            "body_b": lambda: c.body_b.to_numpy()[:n],
            "point": lambda: c.point.to_numpy()[:n],
            "normal": lambda: c.normal.to_numpy()[:n],
            "separation": lambda: c.sep.to_numpy()[:n],
            "impulse": lambda: r.lam_step.to_numpy()[:n],
            "manifold": lambda: c.manifold.to_numpy()[:n],
            "overlap": lambda: c.overlap.to_numpy()[:n],
        }
        if fields is None:
            fields = [k for k in read if k != "impulse" or self.track_impulses]
        elif "impulse" in fields and not self.track_impulses:
            raise SandboxError("contact impulses are summed only while World.track_impulses is True: set it "
                               "before stepping")
        return {k: read[k]() for k in fields}

    def timing_ms(self) -> dict[str, float]:
        return self.profiler.mean_ms()
