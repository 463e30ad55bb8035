"""The web sandbox: a viser server, the simulation thread and the render loop, wired together.

    from web.app import SandboxApp
    app = SandboxApp("playground", port=8080, arch="cpu")
    app.serve_forever()          # or app.start() ... app.stop() from tests and benchmarks

Threads: viser's event loop and its callback pool (GUI events), the simulation thread
(every Taichi call), and the render loop (the caller's thread: snapshots -> scene updates,
stats and plots). All tabs share one world and one panel; closing a tab changes nothing.
"""

from __future__ import annotations

import errno
import signal
import socket
import threading
import time
from pathlib import Path

import numpy as np

from sandbox import SandboxError, resolve_arch, resolve_scene

from .panel import ControlPanel
from .render import WorldView, camera_for, configure_lighting
from .simulation import Simulation

RENDER_HZ = 30.0
STATS_HZ = 4.0
DEFAULT_SCENE = {"cpu": "playground", "cuda": "headline_pile"}


def default_scene(arch: str) -> str:
    """A scene sized for the machine: the 5000-box pile needs a GPU to run in real time."""
    return DEFAULT_SCENE.get(arch, DEFAULT_SCENE["cpu"])


def check_port_free(host: str, port: int) -> None:
    """viser silently moves to the next port when one is busy; a user who asked for a port
    should hear that it is taken instead."""
    if port == 0:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise SandboxError(f"port {port} on {host} is busy (another sandbox or server?): "
                                   f"pass --port with a free port, or --port 0 to pick one") from None
            raise SandboxError(f"cannot listen on {host}:{port}: {exc.strerror}") from None


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _interrupt(signum, frame):
    """SIGTERM, handled as Ctrl+C is (SandboxApp.serve_forever)."""
    raise KeyboardInterrupt


class SandboxApp:
    def __init__(self, scene: str | None = None, *, host: str = "127.0.0.1", port: int = 8080, arch: str = "cpu",
                 solver: str | None = "mass-splitting", iterations: int | None = 15, formulation: str | None = None,
                 recordings_dir: Path = Path("recordings"), log=print):
        self.log = log
        check_port_free(host, port)
        if scene is not None:
            resolve_scene(scene)  # a wrong name fails before Taichi starts
        self.arch = resolve_arch(arch)  # Taichi itself starts in the simulation thread
        self.scene_path = resolve_scene(scene or default_scene(self.arch))
        self.sim = Simulation(self.scene_path, arch=self.arch, solver=solver, iterations=iterations,
                              formulation=formulation, log=log)
        self.host, self.requested_port = host, (port or free_port(host))
        self.recordings_dir = recordings_dir
        self.server = None
        self.render_fps = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = "localhost" if self.host in ("0.0.0.0", "127.0.0.1") else self.host
        return f"http://{host}:{self.server.get_port()}"

    # ------------------------------------------------------------------ lifecycle
    def start(self, background: bool = True) -> str:
        """Build the world (compiling its kernels), start the server; returns the URL."""
        import viser

        self.sim.start()
        self.server = viser.ViserServer(host=self.host, port=self.requested_port, verbose=False)
        if self.server.get_port() != self.requested_port:  # lost a race for the port since the check
            self.server.stop()
            raise SandboxError(f"port {self.requested_port} became busy while starting; pass another --port")
        self._setup_scene()
        self.view = WorldView(self.server, on_pick=self._on_pick)
        self.twin_view: WorldView | None = None  # the compare view's second world, while it is on
        self.panel = ControlPanel(self.server, self.sim, self.recordings_dir)
        if background:
            self._thread = threading.Thread(target=self._render_loop, name="render", daemon=True)
            self._thread.start()
        return self.url

    def serve_forever(self) -> None:
        """Serve until Ctrl+C or a SIGTERM (``kill``, a service manager), both a clean exit: Taichi
        writes the kernels it compiled to its offline cache only when the process exits normally.
        A server stopped by a bare SIGTERM lost them all, and the next start compiled its first
        step again (9.5-11 s, against 4.0-4.4 s after Ctrl+C)."""
        url = self.start(background=False)
        self.log(f"sandbox serve: {url}  (scene {self.scene_path.stem}, {self.sim.world.solver}, {self.arch}; "
                 "Ctrl+C stops)", flush=True)
        previous = signal.signal(signal.SIGTERM, _interrupt)
        try:
            self._render_loop()
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)
            self.stop()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.sim.stop()
        if self.server is not None:
            self.server.stop()

    # ------------------------------------------------------------------ scene and loop
    def _setup_scene(self) -> None:
        s = self.server
        s.gui.configure_theme(control_width="large", dark_mode=False, show_logo=False)
        configure_lighting(s.scene)
        snap = self.sim.latest()
        eye, target = camera_for(snap.positions)
        s.initial_camera.position = eye
        s.initial_camera.look_at = target
        s.initial_camera.up = (0.0, 0.0, 1.0)

    def _show_twin(self, snap, mode: str) -> None:
        """The compare view's second world, drawn COMPARE_GAP to the right of the first."""
        if snap.twin is None:
            if self.twin_view is not None:
                self.twin_view.clear()
                self.twin_view = None
            return
        if self.twin_view is None:
            self.server.scene.add_frame("/twin", show_axes=False, position=(snap.twin.offset, 0.0, 0.0))
            self.twin_view = WorldView(self.server, root="/twin")
            both = np.concatenate([snap.positions, snap.twin.positions + [snap.twin.offset, 0.0, 0.0]])
            self._frame_camera(snap, both)
        self.twin_view.show(snap.twin, None, mode)

    def _frame_camera(self, snap, positions=None) -> None:
        """Point every open tab's camera at the bodies of a newly built world (or at ``positions``)."""
        eye, target = camera_for(snap.positions if positions is None else positions)
        self.server.initial_camera.position = eye
        self.server.initial_camera.look_at = target
        for client in self.server.get_clients().values():
            client.camera.position = eye
            client.camera.look_at = target

    def _on_pick(self, body: int) -> None:
        self.panel.pick(body)

    def _render_loop(self) -> None:
        period = 1.0 / RENDER_HZ
        last_key = None
        framed = None  # the scene the cameras were last pointed at (the first by _setup_scene)
        last_stats = 0.0
        frames, fps_t0 = 0, time.perf_counter()
        while not self._stop.is_set():
            t0 = time.perf_counter()
            snap = self.sim.latest()
            selected, mode = self.panel.selected, self.panel.color_mode  # read once: other threads write them
            paused = snap.inspection["label"] if snap.inspection is not None else None  # a sweep of an inspected step
            twin = (snap.twin.generation, snap.twin.offset) if snap.twin is not None else None
            key = (snap.world_id, snap.generation, snap.step, selected, mode, snap.contacts is None, paused, twin)
            if key != last_key:  # a new frame (or a new look): skipped snapshots are never drawn
                if framed is not None and snap.scene.source != framed:
                    self._frame_camera(snap)  # another scene: frame its bodies (a reset keeps the view)
                framed = snap.scene.source
                self.view.show(snap, selected, mode)
                self._show_twin(snap, mode)
                last_key = key
                frames += 1
            now = time.perf_counter()
            if now - fps_t0 >= 1.0:
                self.render_fps = frames / (now - fps_t0)
                frames, fps_t0 = 0, now
            if now - last_stats >= 1.0 / STATS_HZ:
                self.panel.refresh(snap, self.render_fps)
                last_stats = now
            self._stop.wait(max(0.0, period - (time.perf_counter() - t0)))

