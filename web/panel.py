"""The control panel: every GUI element, what it asks the simulation to do, and the live
stats and plots.

Callbacks run in viser's thread pool, so each one only builds a command and submits it;
the simulation thread applies it between steps (``simulation.Simulation``). A command that
fails shows a notification in the tab that asked for it, and the world goes on.
"""

from __future__ import annotations

import functools
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from sandbox import (EFFECTS, FORMULATIONS, SOLVERS, EventSpec, SandboxError, Scene, Settings, resolve_scene,
                     shipped_scenes)

from .debris import DEBRIS_MIXES, MAX_DEBRIS, debris_bodies
from .readouts import LOG_FLOOR, decades, inspection_text, stats_table
from .render import COLOR_MODES

EFFECT_HINTS = {"sleeping": "Resting islands stop being simulated until something touches them (drawn dimmed); "
                            "untick it to watch a solver's jitter"}
TIME_STEPS = {"1/30 s": 1 / 30, "1/60 s": 1 / 60, "1/120 s": 1 / 120, "1/240 s": 1 / 240}
MAX_ITERATIONS = 100
def _user_action(callback):
    """Run a widget callback only for changes a user made: ``refresh`` writing the world's
    value into a widget fires the callback in the refreshing thread, and that must not echo
    back to the world as a new command."""
    @functools.wraps(callback)
    def guarded(self, event) -> None:
        if getattr(self._local, "syncing", False):
            return
        callback(self, event)
    return guarded


class ControlPanel:
    def __init__(self, server, sim, recordings_dir: Path):
        self.server = server
        self.sim = sim
        self.recordings_dir = Path(recordings_dir)
        self.selected: int | None = None
        self.color_mode = "shape"
        self._seeds = 0  # seeds of debris drops and fractures: a session is repeatable
        self._shown: dict = {}  # what the widgets show, to skip redundant updates
        self._local = threading.local()
        self._plotted = None
        self._inspected = None  # the paused sweep (and body) the solver folder shows
        self._build()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        gui = self.server.gui
        snap = self.sim.latest()
        self.status = gui.add_markdown("**Starting…**")
        with gui.add_folder("Scene"):
            names = [p.stem for p in shipped_scenes()]
            current = self.sim.scene_path.stem
            self.scene = gui.add_dropdown("Scene", names if current in names else [current, *names],
                                          initial_value=current)
            self.scene.on_update(self._on_scene)
            world_buttons = gui.add_button_group("World", ("Play", "Pause", "Step", "Reset"))
            world_buttons.on_click(self._on_world_button)
        with gui.add_folder("Solver"):
            self.solver = gui.add_dropdown("Solver", list(SOLVERS), initial_value=snap.solver)
            self.solver.on_update(self._on_solver)
            shufflers = ", ".join(n for n, info in SOLVERS.items() if "shuffle" in info.defaults)
            self.shuffle = gui.add_checkbox(f"Shuffle order ({shufflers})", False,
                                            hint="Permute contacts and colours every step, as parallel hardware does")
            self.shuffle.on_update(self._on_solver)
            floor, start = Settings().step_sweeps, int(min(snap.iterations, MAX_ITERATIONS))
            self.iterations = gui.add_slider("Iterations", 1, MAX_ITERATIONS, 1, start,
                                             hint=f"Soft step: substeps per step, each a biased and a relax "
                                             f"sweep; below {floor} (the default step_sweeps) a substep sweeps "
                                             f"ceil({floor} / iterations) times of each kind, so fewer iterations "
                                             f"cost about as much as {floor}. Paper: the sweeps of its one solve")
            self.iterations.on_update(self._on_iterations)
            self.formulation = gui.add_dropdown("Formulation", list(FORMULATIONS), initial_value=snap.formulation,
                                                hint="soft-step: Box2D v3's substeps with soft contacts; paper: "
                                                "Tonge et al.'s one velocity solve per step with Baumgarte "
                                                "correction, where parallel PGS jitters")
            self.formulation.on_update(self._on_formulation)
            dt_label = min(TIME_STEPS, key=lambda k: abs(TIME_STEPS[k] - snap.dt))
            self.dt = gui.add_dropdown("Time step", list(TIME_STEPS), initial_value=dt_label)
            self.dt.on_update(self._on_timestep)
            self.substeps = gui.add_slider("Substeps", 1, 8, 1, int(min(snap.substeps, 8)))
            self.substeps.on_update(self._on_timestep)
        with gui.add_folder("Stats", expand_by_default=True):
            self.stats = gui.add_markdown("")
            # decades on a linear axis: uPlot's log axis labels 1e-6 as "0,000", and its x axis
            # reads numbers as clock times unless told they are not
            empty = (np.zeros(1), np.full(1, LOG_FLOOR))
            steps = {"x": {"time": False}}
            self.ke_plot = gui.add_uplot(empty, ({"label": "step"}, {"label": "log10 kinetic energy [J]",
                                                                       "stroke": "#d62728"}),
                                         title="Kinetic energy, log10 J", scales=steps, aspect=1.6)
            self.res_plot = gui.add_uplot(empty, ({"label": "step"}, {"label": "log10 LCP residual RMS [m/s]",
                                                                       "stroke": "#1f77b4"}),
                                          title="Solver residual, log10 m/s", scales=steps, aspect=1.6)
        with gui.add_folder("Effects"):
            self.gravity = gui.add_checkbox("Gravity", snap.gravity_on)
            self.gravity.on_update(self._on_gravity)
            self.effects = {e: gui.add_checkbox(e.capitalize(), e in snap.effects, hint=EFFECT_HINTS.get(e))
                            for e in EFFECTS}
            for box in self.effects.values():
                box.on_update(self._on_effects)
            self.realtime = gui.add_checkbox("Real time", True, hint="Off: step as fast as the machine can")
            self.realtime.on_update(lambda _: self.sim.submit("real time", self._set_realtime(self.realtime.value)))
        with gui.add_folder("Drop debris"):
            self.debris_count = gui.add_slider("Count", 1, MAX_DEBRIS, 1, 20)
            self.debris_mix = gui.add_dropdown("Shapes", DEBRIS_MIXES, initial_value="mixed")
            self.drop = gui.add_button("Drop debris", icon=None)
            self.drop.on_click(self._on_drop)
        with gui.add_folder("Selection"):
            self.selection = gui.add_markdown("Click a body to select it.")
            self.pieces = gui.add_slider("Pieces", 2, 32, 1, 8, hint="Voronoi cells of a convex body "
                                         "(a compound breaks into its convex hulls)")
            self.burst = gui.add_slider("Burst [m/s]", 0.0, 5.0, 0.1, 1.0,
                                        hint="outward speed given to the pieces (momentum is conserved)")
            self.fracture = gui.add_button("Fracture selected", disabled=True)
            self.fracture.on_click(self._on_fracture)
            self.remove = gui.add_button("Remove selected", disabled=True)
            self.remove.on_click(self._on_remove)
        with gui.add_folder("Compare", expand_by_default=False):
            self.compare = gui.add_dropdown("Right-hand world", ("off", *SOLVERS), initial_value="off",
                                            hint="A second world of the same scene with this solver, beside the "
                                            "first: both restart, then take the same drops, removals and settings")
            self.compare.on_update(self._on_compare)
            self.compare_plot = gui.add_uplot((np.zeros(1), np.full(1, LOG_FLOOR), np.full(1, LOG_FLOOR)),
                                              ({"label": "step"},
                                               {"label": "left: log10 KE [J]", "stroke": "#d62728"},
                                               {"label": "right: log10 KE [J]", "stroke": "#1f77b4"}),
                                              title="Kinetic energy, both worlds, log10 J",
                                              scales={"x": {"time": False}}, aspect=1.6)
        with gui.add_folder("Inside the solver", expand_by_default=False):
            self.inspect_buttons = gui.add_button_group("Step", ("Inspect step", "Next sweep", "Finish step"))
            self.inspect_buttons.on_click(self._on_inspect)
            self.inspect_text = gui.add_markdown("Pause the world inside a step: *Inspect step* runs the next step "
                                                 "up to the end of its first sweep, *Next sweep* one sweep further. "
                                                 "Arrows: each contact's normal impulse; points: its residual "
                                                 "(green solved, red not). Select a body to list its sub-bodies.")
            self.sweep_plot = gui.add_uplot((np.zeros(1), np.full(1, LOG_FLOOR)),
                                            ({"label": "sweep"}, {"label": "log10 residual RMS [m/s]",
                                                                  "stroke": "#9467bd"}),
                                            title="This step's residual, log10 m/s, by sweep",
                                            scales={"x": {"time": False}}, aspect=1.6)
        with gui.add_folder("View"):
            self.colors = gui.add_dropdown("Colour by", COLOR_MODES, initial_value="shape",
                                           hint="speed: blue at rest, red moving (jitter shows up)")
            self.colors.on_update(lambda _: setattr(self, "color_mode", self.colors.value))
            self.contacts = gui.add_checkbox("Contact points", False)
            self.contacts.on_update(lambda _: self.sim.submit("contacts", self._set_contacts(self.contacts.value)))
        with gui.add_folder("Record"):
            self.record = gui.add_button_group("Recording", ("Record", "Stop & save"))
            self.record.on_click(self._on_record)
            self.record_status = gui.add_markdown("Not recording.")
    # ------------------------------------------------------------------ callbacks (viser's threads)
    def _next_seed(self) -> int:
        """The seed of the next debris drop or fracture: 1, 2, ... in the order they are asked for."""
        self._seeds += 1
        return self._seeds

    def _notify(self, event, title: str):
        client = getattr(event, "client", None)

        def show(message: str) -> None:
            self._shown.clear()  # the widgets may now show a value the world refused: resync
            if client is not None:
                client.add_notification(title, message, color="red", auto_close_seconds=8.0)
        return show

    @_user_action
    def _on_scene(self, event) -> None:
        name = self.scene.value
        if name == self.sim.scene_path.stem:
            return
        self.selected = None
        threading.Thread(target=self._load_scene, args=(name, event.client), name=f"load {name}", daemon=True).start()

    def _load_scene(self, name: str, client) -> None:
        """Parse (and decompose) the scene in this worker thread; the simulation thread only
        builds the world from it, so the old world keeps running meanwhile."""
        note = None
        if client is not None:
            note = client.add_notification(f"Loading {name}", "reading the scene (mesh decompositions run once, "
                                           "then come from the cache)…", loading=True, with_close_button=False)
        report = self._notify(SimpleNamespace(client=client), "Scene")
        try:
            path = resolve_scene(name)
            scene = Scene.load(path)
        except SandboxError as exc:
            if note is not None:
                note.remove()
            report(str(exc))
            return

        def done(_) -> None:
            if note is not None:
                note.title, note.body, note.loading = f"{name} loaded", f"{len(scene.bodies)} bodies", False
                note.with_close_button, note.auto_close_seconds = True, 3.0

        def failed(message: str) -> None:
            if note is not None:
                note.remove()
            report(message)
        self.sim.submit(f"scene {name}", lambda s: s.load(scene, path), on_error=failed, on_done=done)

    @_user_action
    def _on_world_button(self, event) -> None:
        choice = event.target.value
        if choice == "Play":
            self.sim.submit("play", lambda s: (setattr(s, "playing", True), setattr(s, "last_error", None)))
        elif choice == "Pause":
            self.sim.submit("pause", lambda s: setattr(s, "playing", False))
        elif choice == "Step":
            self.sim.submit("step", lambda s: s.step_once())
        elif choice == "Reset":
            self.selected = None
            self.sim.submit("reset", lambda s: s.load(), on_error=self._notify(event, "Reset"))

    @_user_action
    def _on_compare(self, event) -> None:
        choice = self.compare.value
        solver = None if choice == "off" else choice
        self.sim.submit(f"compare {choice}", lambda s: s.compare(solver), on_error=self._notify(event, "Compare"))

    @_user_action
    def _on_inspect(self, event) -> None:
        action = {"Inspect step": "begin", "Next sweep": "next", "Finish step": "finish"}[event.target.value]
        body = self.selected
        self.sim.submit(f"inspect: {event.target.value.lower()}", lambda s: s.inspect(action, body),
                        on_error=self._notify(event, "Inside the solver"))

    @_user_action
    def _on_solver(self, event) -> None:
        name = self.solver.value
        options = {"shuffle": True} if "shuffle" in SOLVERS[name].defaults and self.shuffle.value else {}
        iterations = int(self.iterations.value)
        ev = EventSpec(time=0.0, kind="solver", solver=name, iterations=iterations, options=options)
        self.sim.submit(f"solver {name} ({iterations} iterations{', shuffled' if options else ''})",
                        lambda s: s.apply(ev), on_error=self._notify(event, "Solver"))

    @_user_action
    def _on_formulation(self, event) -> None:
        ev = EventSpec(time=0.0, kind="formulation", formulation=self.formulation.value)
        self.sim.submit(f"formulation {ev.formulation}", lambda s: s.apply(ev),
                        on_error=self._notify(event, "Formulation"))

    @_user_action
    def _on_iterations(self, event) -> None:
        ev = EventSpec(time=0.0, kind="iterations", iterations=int(self.iterations.value))
        self.sim.submit(f"iterations {ev.iterations}", lambda s: s.apply(ev),
                        on_error=self._notify(event, "Iterations"))

    @_user_action
    def _on_timestep(self, event) -> None:
        ev = EventSpec(time=0.0, kind="timestep", dt=TIME_STEPS[self.dt.value], substeps=int(self.substeps.value))
        self.sim.submit(f"time step {self.dt.value} x {ev.substeps} substeps", lambda s: s.apply(ev),
                        on_error=self._notify(event, "Time step"))

    @_user_action
    def _on_gravity(self, event) -> None:
        on = bool(self.gravity.value)

        def run(s):
            g = s.world.scene.world.gravity if on else np.zeros(3)
            s.apply(EventSpec(time=0.0, kind="gravity", gravity=np.array(g, dtype=np.float64)))
        self.sim.submit(f"gravity {'on' if on else 'off'}", run, on_error=self._notify(event, "Gravity"))

    @_user_action
    def _on_effects(self, event) -> None:
        effects = tuple(sorted(e for e, box in self.effects.items() if box.value))
        ev = EventSpec(time=0.0, kind="effects", effects=effects)
        self.sim.submit(f"effects {list(effects)}", lambda s: s.apply(ev),
                        on_error=self._notify(event, "Effects"))

    @_user_action
    def _on_drop(self, event) -> None:
        count, mix = int(self.debris_count.value), self.debris_mix.value
        seed = self._next_seed()

        def run(s):
            bodies = debris_bodies(s.latest(), count, mix, seed)
            s.apply(EventSpec(time=0.0, kind="drop", new_bodies=bodies))
            return len(bodies)
        self.sim.submit(f"drop {count} {mix}", run, on_error=self._notify(event, "Drop debris"))

    @_user_action
    def _on_fracture(self, event) -> None:
        body = self.selected
        if body is None:
            return
        pieces, burst = int(self.pieces.value), float(self.burst.value)
        seed = self._next_seed()
        self.selected = None

        def run(s):
            mass = s.world.body_specs[body].mass
            ev = EventSpec(time=0.0, kind="fracture", bodies=[body], pieces=pieces, seed=seed,
                           outward_impulse=burst * mass)
            s.apply(ev)
        self.sim.submit(f"fracture body {body} into {pieces} pieces", run, on_error=self._notify(event, "Fracture"))

    @_user_action
    def _on_remove(self, event) -> None:
        body = self.selected
        if body is None:
            return
        self.selected = None
        self.sim.submit(f"remove body {body}", lambda s: s.apply(EventSpec(time=0.0, kind="remove", bodies=[body])),
                        on_error=self._notify(event, "Remove"))

    @_user_action
    def _on_record(self, event) -> None:
        if event.target.value == "Record":
            self.sim.submit("record", lambda s: s.start_recording(), on_error=self._notify(event, "Record"))
            return
        self.recordings_dir.mkdir(parents=True, exist_ok=True)
        path = self.recordings_dir / time.strftime("sandbox-%Y%m%d-%H%M%S.sbrec")
        client = event.client

        def saved(result) -> None:
            if result is None:
                self.record_status.content = "Not recording."
                return
            path_, size, frames = result
            self.record_status.content = f"Saved **{path_.name}**: {frames} frames, {size / 1e6:.2f} MB."
            if client is not None:
                client.send_file_download(path_.name, path_.read_bytes())
        self.sim.submit("stop recording", lambda s: s.stop_recording(path), on_error=self._notify(event, "Record"),
                        on_done=saved)

    @staticmethod
    def _set_realtime(on: bool):
        return lambda s: setattr(s, "realtime", on)

    @staticmethod
    def _set_contacts(on: bool):
        return lambda s: setattr(s, "draw_contacts", on)

    def pick(self, body: int) -> None:
        self.selected = None if self.selected == body else body

    # ------------------------------------------------------------------ refresh (render thread)
    def refresh(self, snap, render_fps: float) -> None:
        """Bring the widgets in line with the world (another tab or a scripted event may have
        changed it) and update the stats and plots."""
        self._sync(self.solver, snap.solver)
        self._sync(self.iterations, min(snap.iterations, MAX_ITERATIONS))
        self._sync(self.formulation, snap.formulation)
        self._sync(self.compare, snap.twin.solver if snap.twin is not None else "off")
        self._sync(self.gravity, snap.gravity_on)
        for e, box in self.effects.items():
            self._sync(box, e in snap.effects)
        if self.sim.scene_path.stem in self.scene.options:
            self._sync(self.scene, self.sim.scene_path.stem)
        state = "▶ running" if snap.playing else "⏸ paused"
        if snap.error and not snap.playing:
            state += f" — {snap.error}"
        rec = " · ⏺ recording" if snap.recording else ""
        paper = " (paper's scheme)" if snap.formulation == "paper" else ""
        if snap.twin is not None:
            rec += f" ‖ right: {snap.twin.solver}, {len(snap.twin.bodies)} bodies"
        self._set(self.status, "content", f"**{self.sim.scene_path.stem}** · {len(snap.bodies)} bodies · "
                                          f"{snap.solver} × {snap.iterations}{paper} · {state}{rec}")
        self._set(self.stats, "content", stats_table(snap, render_fps, self.sim.STATS_WINDOW_S))
        h = snap.history
        if len(h["step"]) and self._plotted != (snap.world_id, snap.step):  # nothing new while paused
            self._plotted = (snap.world_id, snap.step)
            self.ke_plot.data = (h["step"], decades(h["kinetic_energy"]))
            self.res_plot.data = (h["step"], decades(h["residual_rms"]))
            if snap.twin is not None and len(snap.twin.history) == len(h["step"]):
                self.compare_plot.data = (h["step"], decades(h["kinetic_energy"]), decades(snap.twin.history))
        selected = self.selected  # read once: GUI callbacks may change it meanwhile
        if selected is not None and selected >= len(snap.bodies):
            selected = self.selected = None
        if selected is None:
            text = "Click a body to select it."
        else:
            body = snap.bodies[selected]
            kinds = "+".join(s.kind for s in body.shapes)
            text = (f"Body **{selected}**{f' ({body.name})' if body.name else ''}: {kinds}, "
                    f"{'static' if body.static else f'{body.mass:.3g} kg'}, "
                    f"|v| = {snap.speeds[selected]:.3g} m/s{', asleep' if snap.asleep[selected] else ''}")
        self._set(self.selection, "content", text)
        self._set(self.remove, "disabled", selected is None)
        self._set(self.fracture, "disabled", selected is None)
        self._refresh_inspection(snap.inspection)

    def _refresh_inspection(self, view) -> None:
        if view is None:
            if self._inspected is not None:
                self._set(self.inspect_text, "content", "No step paused: *Inspect step* pauses the next one.")
                self._inspected = None
            return
        if self._inspected == view["label"] + str(view["body"]):
            return
        self._inspected = view["label"] + str(view["body"])
        self._set(self.inspect_text, "content", inspection_text(view))
        residuals = view["residuals"]
        self.sweep_plot.data = (np.arange(1, len(residuals) + 1, dtype=np.float64), decades(residuals))

    def _sync(self, handle, value) -> None:
        """Show the world's value without firing the widget's callback again."""
        key = id(handle)
        if self._shown.get(key) != value:
            self._shown[key] = value
            if handle.value != value:
                self._local.syncing = True
                try:
                    handle.value = value
                finally:
                    self._local.syncing = False

    def _set(self, handle, prop: str, value) -> None:
        key = (id(handle), prop)
        if self._shown.get(key) != value:
            self._shown[key] = value
            setattr(handle, prop, value)

