"""The simulation thread: the only thread that touches Taichi.

GUI callbacks run in viser's thread pool; they never call the engine. They ``submit`` a
command (a function of the ``Simulation``), and the simulation thread runs the queued
commands between steps, in order. After every step it publishes an immutable
``Snapshot`` (numpy copies of the poses and the metrics) that the render loop reads
whenever it is ready: rendering never slows the simulation, it only skips snapshots.

The world steps at its fixed dt, paced to real time when it can keep up; when it
cannot, it runs as fast as it can and the stats say so (``realtime_factor``).
"""

from __future__ import annotations

import collections
import queue
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sandbox import EventSpec, Recorder, SandboxError, Scene, SimulationError, init_backend

from .debris import DEBRIS_KINDS, MAX_DEBRIS as DEBRIS_RESERVE
from .snapshot import COMPARE_GAP, Snapshot, inspection_view, twin_view

HISTORY = 600  # published frames kept for the live plots
PUBLISH_HZ = 30.0  # snapshots per second while playing: the renderer draws at most this many
BODY_LIST_KINDS = ("drop", "remove", "fracture")


def web_world(scene: Scene, arch: str, **kwargs):
    """A world as the web sandbox runs it: room for the panel's debris and its shape kinds,
    what a drop launches compiled now (not on the first click), and a sampled step timed launch
    by launch, the fused step's own kernels (profile.py: a per-stage sample compiled a second
    set). ``kwargs``: World's solver, iterations, formulation and solver options."""
    from sandbox import World

    world = World(scene, arch=arch, profile=False, reserve_pieces=DEBRIS_RESERVE, reserve_kinds=DEBRIS_KINDS, **kwargs)
    world.prepare_edits()
    world.profiler.per_stage = False
    return world


@dataclass
class Command:
    label: str
    run: object  # callable(Simulation) -> object
    on_error: object = None  # callable(str) or None
    on_done: object = None  # callable(result) or None


@dataclass
class _Stats:
    window_start: float = field(default_factory=time.perf_counter)
    steps: int = 0
    sim_seconds: float = 0.0
    steps_per_second: float = 0.0
    realtime_factor: float = 0.0
    timing_ms: dict = field(default_factory=dict)  # stages from one sampled step; "total": mean of the rest
    sampled_ms: dict = field(default_factory=dict)
    step_seconds: float = 0.0
    timed_steps: int = 0


class Simulation:
    """Owns the World; ``submit`` commands from any thread, read ``latest`` from any thread."""

    STATS_WINDOW_S = 0.5
    SLOW_STEP_S = 0.5
    """[s] A step slower than this is logged ("slow step"): what the user saw as a stall."""

    def __init__(self, scene_path: Path, *, arch: str = "cpu", solver: str | None = None,
                 iterations: int | None = None, formulation: str | None = None, log=print):
        self.scene_path = Path(scene_path)
        self.arch = arch
        self.solver = solver
        self.iterations = iterations
        self.formulation = formulation  # None: the scene's
        self.log = log
        self.world = None
        self.playing = True
        self.realtime = True
        self.draw_contacts = False
        self.recorder = None
        self.last_error: str | None = None  # why the world paused itself (a diverged step)
        self.inspection = None  # sandbox.inspection.StepInspection while a step is looked inside
        self.inspect_body: int | None = None  # whose sub-bodies the inspection lists
        self._inspect_logged = 0  # events logged before the inspected step (its own are new)
        self.twin = None  # the compare view's second world (compare), stepped and edited with the first
        self._twin_offset = 0.0
        self._twin_generation = 0
        self._queue: queue.Queue[Command] = queue.Queue()
        self._latest: Snapshot | None = None
        self._latest_lock = threading.Lock()
        self._world_id = 0
        self._generation = 0
        self._single_steps = 0
        self._last_publish = 0.0
        self._stop = threading.Event()
        self._ready = threading.Event()
        self._history = {k: collections.deque(maxlen=HISTORY) for k in ("step", "kinetic_energy", "residual_rms")}
        self._stats = _Stats()
        self.startup_error: BaseException | None = None
        self._thread = threading.Thread(target=self._main, name="simulation", daemon=True)

    # ------------------------------------------------------------------ any thread
    def start(self, timeout: float = 600.0) -> None:
        """Start the thread and wait until the first world is built (compiled) or failed."""
        self._thread.start()
        self._ready.wait(timeout)
        if self.startup_error is not None:
            raise self.startup_error

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10.0)

    def submit(self, label: str, run, on_error=None, on_done=None) -> None:
        self._queue.put(Command(label, run, on_error, on_done))

    def latest(self) -> Snapshot | None:
        with self._latest_lock:
            return self._latest

    # ------------------------------------------------------------------ commands (simulation thread)
    def load(self, scene: Scene | None = None, scene_path: Path | None = None) -> None:
        """(Re)build the world: from ``scene`` (parsed off this thread: a mesh scene's first load
        runs CoACD, which must not stall the running world), or the current scene (reset).
        A failure leaves the old world running."""
        if scene is None:
            scene = self.world.scene if self.world is not None else Scene.load(self.scene_path)
        old = self.world
        solver = self.world.solver if self.world is not None else self.solver
        iterations = self.world.iterations if self.world is not None else self.iterations
        options = dict(self.world.solver_options) if self.world is not None else {}
        formulation = self.world.formulation if self.world is not None else self.formulation
        world = web_world(scene, self.arch, solver=solver, iterations=iterations, formulation=formulation,
                          **{k: v for k, v in options.items() if v is not None})
        self.inspection = None  # an inspected step of the old world goes with it
        self.stop_recording()
        twin_solver = self.twin.solver if self.twin is not None else None
        if old is not None:
            old.close()
        self.world = world
        if scene_path is not None:
            self.scene_path = Path(scene_path)
        self._world_id += 1
        self._generation += 1
        for series in self._history.values():
            series.clear()
        self._set_twin(twin_solver)
        self._publish()

    def compare(self, solver: str | None) -> None:
        """The compare view: a second world of the same scene with ``solver`` (None: off), started
        with the first from the scene's beginning, stepped with it and given the same edits (drops,
        removals, iterations, formulation, gravity, effects; not the first world's solver)."""
        self._set_twin(None)  # (so the reload below does not rebuild the old one)
        if solver is not None:
            self.load(self.world.scene)  # both from the start: the same inputs from here on
            self._set_twin(solver)

    def _set_twin(self, solver: str | None) -> None:
        if self.twin is not None:
            self.twin.close()
            self.twin = None
        self._history["twin_kinetic_energy"] = collections.deque(maxlen=HISTORY)
        if solver is None:
            return
        w = self.world
        self.twin = web_world(w.scene, self.arch, solver=solver, iterations=w.iterations, formulation=w.formulation)
        pos = w.state(("position",))["position"]
        self._twin_offset = float(np.ptp(pos[:, 0])) + COMPARE_GAP if len(pos) else COMPARE_GAP
        self._twin_generation += 1

    def apply(self, event: EventSpec) -> None:
        """An edit of the running world, logged like a scripted event (recordings replay it),
        stamped with the world's current time."""
        self._end_inspection()  # an edit applies between steps
        event.time = self.world.step_count * self.world.dt
        logged = len(self.world.applied_events)
        self.world.apply_event(event)
        if self.twin is not None and event.kind != "solver":  # the twin keeps its own solver
            self.twin.apply_event(event)
            if event.kind in BODY_LIST_KINDS:
                self._twin_generation += 1
        self._note_body_list_edits(logged)

    def _note_body_list_edits(self, logged: int) -> None:
        """A new generation when an event logged since ``logged`` changed the body list: the
        panel's edits, and those a step applies itself (scripted events, impact fractures)."""
        if any(e.kind in BODY_LIST_KINDS for _, e in self.world.applied_events[logged:]):
            self._generation += 1

    def inspect(self, action: str, body: int | None = None) -> None:
        """The "Inside the solver" panel: ``begin`` pauses the world and runs the next step up to
        the end of its first sweep, ``next`` to the end of the next sweep (the step completes
        after its last), ``finish`` the rest of the step. ``body``: whose sub-bodies to list."""
        self.inspect_body = body
        if action == "finish":
            self._end_inspection()
            return
        self.playing = False
        if self.inspection is None:
            self._inspect_logged = len(self.world.applied_events)
            self.inspection = self.world.inspect_step()
        try:
            sweep = self.inspection.advance()
        except SimulationError as exc:
            self.inspection = None
            self._paused_by(exc)
            return
        if sweep is None:  # that was the step's last sweep: the step is done
            self.inspection = None
            self._after_step(0.0, profiled=False, logged=self._inspect_logged)

    def _end_inspection(self) -> None:
        """Finish an inspected step (it counts as a step: recorded, published)."""
        if self.inspection is not None:
            inspection, self.inspection = self.inspection, None
            try:
                inspection.finish()
            except SimulationError as exc:
                self._paused_by(exc)
                return
            self._after_step(0.0, profiled=False, logged=self._inspect_logged)
            self._publish(new_frame=True)

    def step_once(self) -> None:
        self.playing = False
        self._single_steps += 1

    def start_recording(self) -> None:
        if self.recorder is None:
            self.recorder = Recorder(self.world, self.scene_path)

    def stop_recording(self, path: Path | None = None) -> tuple[Path, int, int] | None:
        """Stop; with ``path``, save there. Returns (path, bytes, frames) when saved."""
        recorder, self.recorder = self.recorder, None
        if recorder is None or path is None:
            return None
        size = recorder.save(path)
        return Path(path), size, recorder.frame_count

    # ------------------------------------------------------------------ the thread
    def _main(self) -> None:
        try:
            init_backend(self.arch)  # Taichi belongs to the thread that starts it: this one
            self.load()
        except BaseException as exc:  # reported to the starting thread, which raises it
            self.startup_error = exc
            self._ready.set()
            return
        self._ready.set()
        next_tick = time.perf_counter()
        while not self._stop.is_set():
            self._run_commands()
            if not (self.playing or self._single_steps):
                time.sleep(0.01)
                next_tick = time.perf_counter()
                continue
            self._single_steps = max(0, self._single_steps - 1)
            if self._step() and (not self.playing or time.perf_counter() - self._last_publish >= 1.0 / PUBLISH_HZ):
                self._publish(new_frame=True)
            if self.realtime:
                next_tick += self.world.dt
                lag = next_tick - time.perf_counter()
                if lag > 0:
                    time.sleep(lag)
                elif lag < -0.25:  # cannot keep up: do not try to catch up later
                    next_tick = time.perf_counter()

    def _run_commands(self) -> None:
        while True:
            try:
                cmd = self._queue.get_nowait()
            except queue.Empty:
                return
            try:
                result = cmd.run(self)
            except SandboxError as exc:
                self._report(cmd, f"{cmd.label}: {exc}")
            except Exception as exc:  # a GUI action must never kill the simulation thread
                traceback.print_exc()
                self._report(cmd, f"{cmd.label} failed: {type(exc).__name__}: {exc}")
            else:
                self.log(f"[sandbox] {cmd.label}")
                _in_background(cmd.on_done, result)
                self._publish()

    def _report(self, cmd: Command, message: str) -> None:
        self.log(f"[sandbox] {message}")
        _in_background(cmd.on_error, message)

    def _step(self) -> bool:
        """One step. Once per stats window the step is profiled launch by launch (the fused step
        with a sync between its launches: the same kernels, so sampling compiles nothing), the
        others run at full speed and are timed as a whole. A step being inspected is finished
        instead."""
        if self.inspection is not None:
            self._end_inspection()
            return True
        s = self._stats
        profiled = s.timing_ms == {} or s.steps == 0
        profiler = self.world.profiler
        if profiled:
            profiler.reset()
        profiler.enabled = profiled
        logged = len(self.world.applied_events)
        t0, cpu0, all0 = time.perf_counter(), time.thread_time(), time.process_time()
        try:
            self.world.step(1)
        except SimulationError as exc:
            self._paused_by(exc)
            return False
        finally:
            profiler.enabled = False
        seconds = time.perf_counter() - t0
        if seconds > self.SLOW_STEP_S:
            # the thread's own CPU time tells a compile (Taichi compiles on the calling thread) from
            # a step that waited; the process's (Taichi's workers, the server's other threads
            # included) tells a step that waited for the server's own work from one descheduled
            self.log(f"[sandbox] slow step {self.world.step_count}: {1e3 * seconds:.0f} ms, "
                     f"{1e3 * (time.thread_time() - cpu0):.0f} ms of it on this thread's CPU, "
                     f"{1e3 * (time.process_time() - all0):.0f} ms on the process's"
                     + (" (the world's first: its kernels compile)" if self.world.step_count == 1 else ""))
        self._after_step(seconds, profiled, logged)
        return True

    def _paused_by(self, exc: SimulationError) -> None:
        self.playing = False
        self.last_error = str(exc)
        self.log(f"[sandbox] paused: {exc}")

    def _after_step(self, seconds: float, profiled: bool, logged: int) -> None:
        """What every completed step updates: the compare view's second world (one step too), the
        body list's generation, the stats, the recording."""
        s = self._stats
        if self.twin is not None:
            twin_logged = len(self.twin.applied_events)
            try:
                self.twin.step(1)
            except SimulationError as exc:
                self._paused_by(SimulationError(f"the compare view's {self.twin.solver} world: {exc}"))
            if any(e.kind in BODY_LIST_KINDS for _, e in self.twin.applied_events[twin_logged:]):
                self._twin_generation += 1
        now = time.perf_counter()
        self._note_body_list_edits(logged)
        if profiled:
            s.sampled_ms = self.world.timing_ms()
        elif seconds > 0.0:
            s.step_seconds += seconds
            s.timed_steps += 1
        if self.recorder is not None:
            self.recorder.capture()
        s.steps += 1
        s.sim_seconds += self.world.dt
        if now - s.window_start >= self.STATS_WINDOW_S:
            wall = now - s.window_start
            s.steps_per_second = s.steps / wall
            s.realtime_factor = s.sim_seconds / wall
            s.timing_ms = dict(s.sampled_ms)
            if s.timed_steps:
                s.timing_ms["total"] = 1e3 * s.step_seconds / s.timed_steps
            s.window_start, s.steps, s.sim_seconds, s.step_seconds, s.timed_steps = now, 0, 0.0, 0.0, 0

    def _publish(self, new_frame: bool = False) -> None:
        self._last_publish = time.perf_counter()
        w = self.world
        st = w.state(("position", "orientation", "linear_velocity"))
        m = w.metrics()
        if new_frame:
            self._history["step"].append(float(w.step_count))
            self._history["kinetic_energy"].append(max(m["kinetic_energy"], 1e-12))  # log-scale plot
            self._history["residual_rms"].append(max(m["residual_rms"], 1e-12))
            if self.twin is not None:
                self._history["twin_kinetic_energy"].append(max(self.twin.metrics()["kinetic_energy"], 1e-12))
        contacts = None
        if self.draw_contacts:
            c = w.contacts(("point", "normal"))
            contacts = {"point": c["point"].astype(np.float32), "normal": c["normal"].astype(np.float32)}
        snap = Snapshot(
            world_id=self._world_id,
            generation=self._generation,
            step=w.step_count,
            positions=st["position"].astype(np.float32),
            orientations=st["orientation"].astype(np.float32),
            speeds=np.linalg.norm(st["linear_velocity"], axis=1).astype(np.float32),
            asleep=w.asleep(),
            bodies=w.body_specs if self._latest is None or self._latest.generation != self._generation
            else self._latest.bodies,
            scene=w.scene,
            metrics=m,
            history={k: np.asarray(v, dtype=np.float64) for k, v in self._history.items()},
            timing_ms=dict(self._stats.timing_ms),
            steps_per_second=self._stats.steps_per_second,
            realtime_factor=self._stats.realtime_factor,
            solver=w.solver,
            iterations=w.iterations,
            formulation=w.formulation,
            dt=w.dt,
            substeps=w.substeps,
            effects=w.effects,
            gravity_on=bool(np.any(w.gravity != 0.0)),
            playing=self.playing,
            recording=self.recorder is not None,
            contacts=contacts,
            inspection=inspection_view(self.inspection, self.world, self.inspect_body),
            twin=twin_view(self.twin, self._world_id, self._twin_generation, self._history["twin_kinetic_energy"],
                           self._twin_offset),
            error=self.last_error,
        )
        with self._latest_lock:
            self._latest = snap


def _in_background(callback, value) -> None:
    """GUI follow-ups (notifications, a recording's download) run off the simulation thread."""
    if callback is not None:
        threading.Thread(target=callback, args=(value,), daemon=True).start()
