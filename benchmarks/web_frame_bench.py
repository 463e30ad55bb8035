"""Web sandbox frame costs: what one rendered frame costs the server, and the frame rate a
headless browser sees.

    python benchmarks/web_frame_bench.py                 # 1000 and 5000 bodies
    python benchmarks/web_frame_bench.py --bodies 1000 --no-browser

Per body count N (a grid of unit boxes, poses changing every frame like a running pile):
* server: ``WorldView.show`` (all poses into the batched node, inside one atomic update) and the
  simulation thread's snapshot (``World.state()`` + ``World.metrics()``) on the same bodies;
* client: headless Chromium (software WebGL, as in CI) connected while the server pushes
  frames at 30 Hz; frames per second counted with requestAnimationFrame in the page.
Prints a table; CPU figures are noisy on a shared 2-core machine: compare within one run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time
from types import SimpleNamespace

import numpy as np

os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


def grid_scene(n: int):
    from sandbox import Scene

    side = int(np.ceil(n ** (1 / 3)))
    return Scene.from_dict({
        "static": [{"shape": "plane", "normal": [0, 0, 1]}],
        "generate": [{"kind": "grid", "counts": [side, side, int(np.ceil(n / side**2))], "spacing": [1.1, 1.1, 1.1],
                      "origin": [0, 0, 0.5], "half_extents": [0.5, 0.5, 0.5]}],
    })


class FakeFrames:
    """Snapshots of the scene's first ``n`` bodies, moved a little every frame (the rest poses
    are read from the BodySpecs once)."""

    def __init__(self, scene, n: int):
        self.scene, self.n = scene, n
        self.bodies = tuple(scene.bodies[:n])
        self.rest = np.array([b.position for b in self.bodies], dtype=np.float32)
        self.quat = np.tile(np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32), (n, 1))

    def __call__(self, frame: int):
        pos = self.rest.copy()
        pos[:, 2] += 0.01 * np.sin(frame * 0.1 + np.arange(self.n))
        return SimpleNamespace(world_id=1, generation=1, step=frame, positions=pos, orientations=self.quat,
                               speeds=np.zeros(self.n, np.float32), bodies=self.bodies, scene=self.scene,
                               contacts=None)


def server_cost(server, scene, n: int, frames: int = 200) -> dict:
    from web.render import WorldView

    view = WorldView(server)
    fake = FakeFrames(scene, n)
    snaps = [fake(k) for k in range(frames + 1)]
    view.show(snaps[0])  # creates the batched node
    times = []
    for snap in snaps[1:]:
        t = time.perf_counter()
        view.show(snap)
        times.append(1e3 * (time.perf_counter() - t))
    return {"show_median_ms": statistics.median(times), "show_p90_ms": float(np.percentile(times, 90))}


def snapshot_cost(scene, n: int, steps: int = 50) -> dict:
    from sandbox import World

    world = World(scene, solver="mass-splitting", iterations=15, arch="cpu")
    world.step(2)
    times = []
    for _ in range(steps):
        t = time.perf_counter()
        world.state()
        world.metrics()
        times.append(1e3 * (time.perf_counter() - t))
    world.close()
    return {"snapshot_median_ms": statistics.median(times)}


def client_fps(server, scene, n: int, seconds: float = 8.0) -> dict:
    from playwright.sync_api import sync_playwright

    from web.browser import CHROMIUM_ARGS, chromium_path

    from web.render import WorldView

    stop = threading.Event()
    pushed = [0]

    fake = FakeFrames(scene, n)

    def pusher():
        view = WorldView(server)
        k = 0
        while not stop.is_set():
            view.show(fake(k))
            pushed[0] += 1
            k += 1
            stop.wait(1 / 30)

    thread = threading.Thread(target=pusher, daemon=True)
    thread.start()
    url = f"http://localhost:{server.get_port()}"
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium_path(), headless=True, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(url)
        page.wait_for_selector("canvas", timeout=60_000)
        time.sleep(3.0)  # first frames and shader compilation
        pushed0, t0 = pushed[0], time.perf_counter()
        fps = page.evaluate("""(seconds) => new Promise(done => {
            let frames = 0; const t0 = performance.now();
            function tick() { frames++; if (performance.now() - t0 < seconds * 1000) requestAnimationFrame(tick);
                              else done(frames * 1000 / (performance.now() - t0)); }
            requestAnimationFrame(tick); })""", seconds)
        pushed_hz = (pushed[0] - pushed0) / (time.perf_counter() - t0)
        browser.close()
    stop.set()
    thread.join()
    return {"client_fps": fps, "server_pushed_hz": pushed_hz}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bodies", default="1000,5000", help="comma-separated body counts")
    ap.add_argument("--no-browser", action="store_true", help="server-side costs only")
    args = ap.parse_args()
    import viser

    from sandbox import backend

    backend.init("cpu")
    counts = [int(x) for x in args.bodies.split(",")]
    scene = grid_scene(max(counts))
    from web.app import free_port
    from web.render import configure_lighting

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    configure_lighting(server.scene)
    server.initial_camera.position = (30.0, -40.0, 25.0)
    server.initial_camera.look_at = (8.0, 8.0, 3.0)
    rows = []
    for n in counts:
        row = {"bodies": n}
        row.update(server_cost(server, scene, n))
        row.update(snapshot_cost(grid_scene(n), n))
        if not args.no_browser:
            row.update(client_fps(server, scene, n))
        rows.append(row)
        server.scene.reset()
        configure_lighting(server.scene)  # reset() removed the lights with every other node
    server.stop()
    keys = list(rows[0])
    print(" | ".join(f"{k:>18s}" for k in keys))
    for row in rows:
        print(" | ".join(f"{row[k]:>18.3f}" if isinstance(row[k], float) else f"{row[k]:>18d}" for k in keys))


if __name__ == "__main__":
    main()
