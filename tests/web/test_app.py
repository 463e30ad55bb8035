"""The web sandbox in a real browser: Debian's Chromium driven by Playwright against a
``sandbox serve`` started here on a free localhost port.

Without a browser the test skips on a developer machine but fails under CI (CI=true):
``.ci/run`` installs Chromium, so a missing one there is a broken set-up, not a reason to skip.
"""

from __future__ import annotations

import io
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from sandbox import Settings

from tests.helpers import TEST_ARCH
from web.app import free_port
from web.browser import CHROMIUM_ARGS, chromium_path

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "tests" / "data" / "web_scene.toml"
ARTIFACTS = Path(os.environ.get("SANDBOX_ARTIFACTS", ROOT / "artifacts"))
START_TIMEOUT_S = 300  # compiling the kernels on a busy 2-core machine


def _no_browser(reason: str):
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"CI=true but no browser could be started: {reason}")
    pytest.skip(reason)


class Server:
    """``sandbox serve`` in a subprocess; its output is collected for assertions."""

    def __init__(self, *args: str):
        self.port = free_port()
        env = {**os.environ, "TI_SKIP_VERSION_CHECK": "ON", "PYTHONUNBUFFERED": "1"}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "sandbox.cli", "serve", *args, "--port", str(self.port), "--arch", "cpu"],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, pattern: str, timeout: float) -> re.Match:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.lines):
                m = re.search(pattern, line)
                if m:
                    return m
            if self.proc.poll() is not None:
                time.sleep(0.2)  # let the reader drain the last lines
                raise AssertionError(f"server exited ({self.proc.returncode}) before {pattern!r}:\n" + self.output)
            time.sleep(0.1)
        raise AssertionError(f"no {pattern!r} from the server within {timeout} s:\n" + self.output)

    @property
    def output(self) -> str:
        return "\n".join(self.lines)

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()


@pytest.fixture(scope="module")
def browser():
    chromium = chromium_path()
    if chromium is None:
        _no_browser("no Chromium found (apt-get install chromium, or set SANDBOX_CHROMIUM)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _no_browser("playwright is not installed (pip install -e '.[test]')")
    with sync_playwright() as p:
        try:
            b = p.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_ARGS)
        except Exception as exc:  # any launch failure is "no browser"
            _no_browser(f"Chromium at {chromium} did not start: {exc}")
        yield b
        b.close()


def _yield_to_the_server() -> None:
    """Let this run's other pytest-xdist workers (this process's siblings) run only when the server,
    the browser and this test leave a core idle, by lowering every thread of theirs to the lowest
    priority (nice 19; allowed for one's own processes). The stall criterion is the server's step
    time as a user sees it; on the 2-core CI machine the sibling's Taichi compiles share the cores
    with it (a failing step took 624 ms, 12 ms of it on the simulation thread's CPU). Kept for the
    rest of the run (lowering a priority is allowed, raising it back is not)."""
    if "PYTEST_XDIST_WORKER" not in os.environ or not Path("/proc/self/task").exists():
        return
    parent, me = os.getppid(), os.getpid()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == me:
            continue
        try:
            if int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1]) != parent:
                continue
            for task in (entry / "task").iterdir():
                os.setpriority(os.PRIO_PROCESS, int(task.name), 19)
        except (OSError, ValueError, IndexError):  # it ended meanwhile, or is not ours
            continue


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    recordings = tmp_path_factory.mktemp("recordings")
    _yield_to_the_server()
    s = Server(str(SCENE), "--solver", "mass-splitting", "--iterations", "15", "--recordings", str(recordings))
    s.recordings = recordings
    try:
        s.url = s.wait_for(r"sandbox serve: (http://\S+)", START_TIMEOUT_S).group(1)
        yield s
    finally:
        s.stop()


def _status(page) -> str:
    return page.get_by_text(re.compile(r"\d+ bodies")).first.inner_text()


def _wait_status(page, pattern: str, timeout: float = 60.0) -> re.Match:
    deadline = time.monotonic() + timeout
    text = ""
    while time.monotonic() < deadline:
        text = _status(page)
        m = re.search(pattern, text)
        if m:
            return m
        time.sleep(0.25)
    raise AssertionError(f"status never matched {pattern!r}; last: {text!r}")


def _step(page) -> int:
    """The world's step count, from the stats table ("338 (t = 5.63 s)")."""
    return int(page.get_by_text(re.compile(r"\(t = [\d.]+ s\)")).first.inner_text().split()[0])


def _choose(page, label: str, option: str) -> None:
    page.get_by_label(label, exact=True).click()
    page.get_by_role("option", name=option, exact=True).click()


def _magenta_pixels(canvas) -> int:
    """Pixels of the canvas in the inspected step's arrow colour (web/render.py ARROW)."""
    import matplotlib.image

    rgb = (matplotlib.image.imread(io.BytesIO(canvas.screenshot()), format="png")[..., :3] * 255).astype(int)
    return int(np.sum((rgb[..., 0] > 200) & (rgb[..., 1] < 90) & (rgb[..., 2] > 150)))


def test_browser_session(browser, server):
    import matplotlib.image

    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.goto(server.url)
    # the panel reaches the page once the server's loop runs: its first steps compile kernels,
    # which on a slow 2-core VM beside a compiling sibling worker took over 60 s (a Zen 3 VM,
    # 2026-12-02; alone there the whole test passed in 3.5 min), so the start's own allowance
    page.get_by_role("button", name="Drop debris").wait_for(state="visible", timeout=START_TIMEOUT_S * 1000)
    n0 = int(_wait_status(page, r"(\d+) bodies").group(1))
    assert n0 == 4

    # The 3D canvas shows the world: many colours, not one blank fill.
    canvas = page.locator("canvas").first
    pixels = matplotlib.image.imread(io.BytesIO(canvas.screenshot()), format="png")[..., :3]
    colours = np.unique((pixels.reshape(-1, 3) * 255).astype(np.uint8), axis=0)
    background = np.all(np.abs(pixels - pixels[0, 0]) < 0.02, axis=-1)
    assert len(colours) > 50, f"canvas looks blank: {len(colours)} distinct colours"
    assert 0.02 < background.mean() < 0.98 or len(colours) > 500

    # Record what follows (the world has been running: the recording starts mid-run).
    page.get_by_role("button", name="Record", exact=True).click()
    _wait_status(page, r"recording")

    # Drop debris: the body count in the page rises by the count asked for. The server logs every
    # step slower than 0.5 s; past the world's first (which compiles its kernels), no step logs
    # one: the sampled steps time the fused launches (nothing more to compile; a per-stage sample
    # paused the world 4-11 s at step 3), and the first drop of every shape mix finds the world
    # built ready for it (web/simulation.py).
    deadline = time.monotonic() + 60
    while _step(page) < 2 and time.monotonic() < deadline:
        time.sleep(0.2)
    logged = len(server.lines)
    _choose(page, "Shapes", "boxes")
    page.get_by_role("button", name="Drop debris").click()
    n1 = int(_wait_status(page, rf"({n0 + 20}) bodies").group(1))
    assert n1 == n0 + 20
    server.wait_for(r"\[sandbox\] drop 20 boxes", 30)
    for k, mix in enumerate(("mixed", "spheres", "hulls", "capsules"), start=2):
        _choose(page, "Shapes", mix)
        page.get_by_role("button", name="Drop debris").click()
        _wait_status(page, rf"{n0 + 20 * k} bodies")
    step = _step(page)
    while _step(page) < step + 30:  # the last drop's bodies in the world for half a second
        time.sleep(0.2)
    slow = [line for line in server.lines[logged:] if "slow step" in line]
    assert not slow, slow

    # The solver dropdown switches the server's solver (its log and the page's status line,
    # which is read back from the world).
    _choose(page, "Solver", "pgs-colored")
    server.wait_for(r"\[sandbox\] solver pgs-colored \(15 iterations\)", 60)
    _wait_status(page, r"pgs-colored × 15")
    # ... and the formulation dropdown the time-stepping scheme (docs/formulation.md)
    _choose(page, "Formulation", "paper")
    server.wait_for(r"\[sandbox\] formulation paper", 60)
    _wait_status(page, r"pgs-colored × 15 \(paper's scheme\)")

    # Stop and save: the file replays bit for bit, drop, solver and formulation switches included.
    page.get_by_role("button", name="Stop & save").click()
    page.get_by_text(re.compile(r"Saved .*frames")).wait_for(timeout=60_000)
    (saved,) = server.recordings.glob("*.sbrec")
    from sandbox.recording import load, replay

    header, frames = load(saved)
    kinds = [e[1]["kind"] for e in header["events"]]
    assert header["start_step"] > 0 and {"drop", "solver", "formulation"} <= set(kinds) and len(frames) > 1
    if TEST_ARCH == "cpu":  # the server ran on the CPU; bit-for-bit replay is a CPU promise
        result = replay(saved, arch=TEST_ARCH)
        assert result["first_departure"] is None, result
    _choose(page, "Formulation", "soft-step")  # the rest of the session on the default scheme
    server.wait_for(r"\[sandbox\] formulation soft-step", 60)

    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    shot = ARTIFACTS / "web_sandbox.png"
    page.screenshot(path=str(shot))
    assert shot.stat().st_size > 10_000

    # Click the middle of the bodies, which the camera frames left of the panel (web/render.py,
    # PANEL_SHIFT: 40 % of the view's width here): the static pedestal is selected; fracturing it
    # fails with a notification in the page, and the world goes on.
    box = canvas.bounding_box()
    cx, cy = box["x"] + 0.4 * box["width"], box["y"] + box["height"] / 2
    page.mouse.click(cx, cy)
    page.get_by_text(re.compile(r"Body 0 \(pedestal\): box, static")).wait_for(timeout=30_000)
    page.get_by_role("button", name="Fracture selected").click()
    page.get_by_text(re.compile(r"body 0 \('pedestal'\) is static and cannot be fractured")).wait_for(timeout=30_000)
    step = _step(page)
    time.sleep(1.5)
    assert _step(page) > step

    # The box resting on the pedestal is just above the middle: select it and fracture it.
    for dy in range(15, 300, 15):
        page.mouse.click(cx, cy - dy)
        time.sleep(0.6)
        if page.get_by_text(re.compile(r"Body 1 \(on_top\)")).count():
            break
    else:
        raise AssertionError("clicking above the pedestal never selected the box on it")
    # Inside the solver, under mass splitting: the next step paused after its first sweep shows
    # the contacts' impulse arrows (magenta, through bodies drawn translucent) and the selected
    # box's sub-bodies, one per contact point touching it, with their merge; one sweep further is
    # the substep's relax sweep.
    _choose(page, "Solver", "mass-splitting")
    server.wait_for(r"\[sandbox\] solver mass-splitting", 60)
    page.get_by_text("Inside the solver", exact=True).click()
    arrows_before = _magenta_pixels(canvas)
    page.get_by_role("button", name="Inspect step").click()
    page.get_by_text(re.compile(r"substep 1/15: biased sweep 1/1")).wait_for(timeout=60_000)
    page.get_by_text(re.compile(r"Sub-bodies of body 1 \(split")).wait_for(timeout=30_000)
    assert page.get_by_text(re.compile(r"^merged$")).count() == 1
    # Before, no pixel has the arrows' colour (measured 0); the arrows are 4 px wide, so even a
    # few make hundreds (measured 442 to over 900 after the first rendered frame).
    deadline, arrows = time.monotonic() + 20, 0
    while arrows <= arrows_before + 100 and time.monotonic() < deadline:
        time.sleep(0.5)
        arrows = _magenta_pixels(canvas)
    page.screenshot(path=str(ARTIFACTS / "web_inspection.png"))
    assert arrows > arrows_before + 100, (arrows_before, arrows)
    # a light body under a heavy one (solvers/light_bodies.py) adds extra biased sweeps before the relax
    for j in range(1, 2 + Settings().ratio_sweeps):
        page.get_by_role("button", name="Next sweep").click()
        label = page.get_by_text(re.compile(rf"substep 1/15: (extra biased sweep {j}/\d|relax sweep 1/1)"))
        label.wait_for(timeout=30_000)
        if "relax" in label.inner_text():
            break
    else:
        raise AssertionError("no relax sweep after the biased and extra sweeps")
    page.get_by_role("button", name="Finish step").click()
    page.get_by_text(re.compile(r"No step paused")).wait_for(timeout=30_000)
    page.get_by_role("button", name="Play").click()

    n2 = int(_wait_status(page, r"(\d+) bodies").group(1))
    page.get_by_role("button", name="Fracture selected").click()
    _wait_status(page, rf"{n2 + 7} bodies")
    server.wait_for(r"\[sandbox\] fracture body 1 into 8 pieces", 30)

    # The compare view: a second world of the scene with shuffled parallel PGS beside the first;
    # both restart from the scene, and a drop reaches both.
    page.get_by_text("Compare", exact=True).click()
    _choose(page, "Right-hand world", "pgs-colored")
    server.wait_for(r"\[sandbox\] compare pgs-colored", 120)
    n3 = int(_wait_status(page, r"(\d+) bodies · mass-splitting.*right: pgs-colored, \d+ bodies").group(1))
    _choose(page, "Shapes", "boxes")
    page.get_by_role("button", name="Drop debris").click()
    _wait_status(page, rf"{n3 + 20} bodies · mass-splitting.*right: pgs-colored, {n3 + 20} bodies")
    time.sleep(2.0)
    page.screenshot(path=str(ARTIFACTS / "web_compare.png"))
    _choose(page, "Right-hand world", "off")
    server.wait_for(r"\[sandbox\] compare off", 60)

    # Contact drawing and a scene change: the world is rebuilt, the solver kept.
    page.get_by_label("Contact points", exact=True).check()
    server.wait_for(r"\[sandbox\] contacts", 30)
    _choose(page, "Scene", "box_on_plane")
    _wait_status(page, r"box_on_plane · 1 bodies · mass-splitting × 15")
    page.close()


def test_second_tab_sees_the_same_world_and_closing_one_keeps_the_server(browser, server):
    first = browser.new_page()
    first.goto(server.url)
    first.get_by_role("button", name="Drop debris").wait_for(state="visible", timeout=60_000)
    bodies = _wait_status(first, r"(\d+) bodies").group(1)
    first.close()
    second = browser.new_page()
    second.goto(server.url)
    second.get_by_role("button", name="Drop debris").wait_for(state="visible", timeout=60_000)
    assert _wait_status(second, r"(\d+) bodies").group(1) == bodies
    assert server.proc.poll() is None
    second.close()


def test_unknown_scene_and_busy_port_are_clear_errors():
    env = {**os.environ, "TI_SKIP_VERSION_CHECK": "ON"}
    bad = subprocess.run([sys.executable, "-m", "sandbox.cli", "serve", "no_such_scene", "--port", "0"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2
    assert "no scene file 'no_such_scene'" in bad.stderr and "Traceback" not in bad.stderr
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        busy = subprocess.run([sys.executable, "-m", "sandbox.cli", "serve", str(SCENE), "--port", str(port)],
                              cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert busy.returncode == 2
    assert f"port {port} on 127.0.0.1 is busy" in busy.stderr and "Traceback" not in busy.stderr


def test_a_terminated_server_exits_cleanly(server):
    """SIGTERM (``kill``, a service manager, this test's fixture) stops the server as Ctrl+C does,
    through a normal exit: only then does Taichi write the kernels it compiled to its offline
    cache (a bare SIGTERM lost them, and the next start compiled for ~20 s). Runs last in this
    module: it stops the module's server."""
    server.proc.terminate()
    assert server.proc.wait(timeout=60) == 0, server.output[-2000:]
