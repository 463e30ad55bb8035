"""Recording and replay: a scripted drop replays bit for bit; an edited file is caught."""

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from sandbox import Scene, SandboxError, World
from sandbox.recording import MAGIC, Recorder, load, replay
from tests.helpers import TEST_ARCH

SCENE_PATH = Path(__file__).resolve().parent.parent / "scenes" / "scripted_drop_300.toml"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    world = World(Scene.load(SCENE_PATH), arch=TEST_ARCH)
    rec = Recorder(world, SCENE_PATH)
    for _ in range(90):
        world.step(1)
        rec.capture()
    assert world.body_count == 320  # the drop at t = 1 s (step 60) happened
    path = d / "drop.sbrec"
    size = rec.save(path)
    return path, size


def test_scripted_drop_replays_bit_for_bit(recorded):
    path, size = recorded
    header, frames = load(path)
    assert len(frames) == 91 and frames[0].shape == (300, 7) and frames[-1].shape == (320, 7)
    assert [e[0] for e in header["events"]] == [60]
    result = replay(path, arch=TEST_ARCH)
    assert result["first_departure"] is None and result["max_difference"] == 0.0


def test_edited_recording_departs_at_the_edited_frame(recorded, tmp_path):
    path, _ = recorded
    header, frames = load(path)
    frames[45] = frames[45].copy()
    frames[45][7, 2] += 1e-3  # nudge one body's height in frame 45
    edited = tmp_path / "edited.sbrec"
    # re-encode with the same layout as Recorder.save
    blob = path.read_bytes()
    head_len = struct.unpack_from("<HI", blob, len(MAGIC))[1]
    prefix = blob[: len(MAGIC) + 6 + head_len]
    raw, prev = b"", None
    for f in frames:
        bits = np.ascontiguousarray(f).view(np.uint32)
        data = bits ^ prev if prev is not None and prev.shape == bits.shape else bits
        raw += struct.pack("<I", len(f)) + data.tobytes()
        prev = bits
    edited.write_bytes(prefix + zlib.compress(raw))
    result = replay(edited, arch=TEST_ARCH)
    assert result["first_departure"] == 45


def test_bad_recordings_get_clear_errors(tmp_path):
    bad = tmp_path / "bad.sbrec"
    bad.write_bytes(b"hello")
    with pytest.raises(SandboxError, match="not a sandbox recording"):
        load(bad)
    bad.write_bytes(MAGIC + struct.pack("<HI", 99, 0))
    with pytest.raises(SandboxError, match="format version 99"):
        load(bad)
    with pytest.raises(SandboxError, match="cannot read"):
        load(tmp_path / "missing.sbrec")


def test_a_recording_that_cannot_be_written_keeps_its_frames(tmp_path):
    world = World(Scene.load(SCENE_PATH), arch=TEST_ARCH)
    rec = Recorder(world, SCENE_PATH)
    for _ in range(3):
        world.step(1)
        rec.capture()
    with pytest.raises(SandboxError, match="cannot write it"):
        rec.save(tmp_path / "no such folder" / "drop.sbrec")
    rec.save(tmp_path / "drop.sbrec")  # the same recorder, saved again: nothing was lost
    assert len(load(tmp_path / "drop.sbrec")[1]) == 4


def test_recording_started_mid_run_replays_through_the_logged_edits(tmp_path):
    """The web sandbox's Record button: frames start late, edits happen before and during."""
    from sandbox.scene.spec import EventSpec

    scene = Scene.load(SCENE_PATH)
    world = World(scene, solver="mass-splitting", iterations=8, arch=TEST_ARCH)
    world.step(20)
    world.apply_event(EventSpec(time=0.0, kind="solver", solver="pgs", iterations=6))
    world.apply_event(EventSpec(time=0.0, kind="gravity", gravity=np.array([0.0, 1.0, -9.81])))
    world.step(5)
    rec = Recorder(world, SCENE_PATH)
    world.apply_event(EventSpec(time=0.0, kind="effects", effects=("restitution",)))
    world.apply_event(EventSpec(time=0.0, kind="timestep", dt=1.0 / 120.0, substeps=2))
    for _ in range(15):
        world.step(1)
        rec.capture()
    path = tmp_path / "mid.sbrec"
    rec.save(path)
    header, frames = load(path)
    assert header["start_step"] == 25 and header["start_events"] == 2 and header["solver"] == "mass-splitting"
    result = replay(path, arch=TEST_ARCH)
    assert result["first_departure"] is None and result["max_difference"] == 0.0
