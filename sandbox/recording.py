"""Recordings: a scene, its settings, every event applied, and every frame's body transforms,
in one compact file; and the replay that re-simulates and finds where a run departs.

File layout (version 1): the magic ``SBXREC`` + 2-byte version, a 4-byte header length, a
JSON header (scene source text, settings, solver, events with the step they were applied
at), then a zlib stream of frames. A frame is the body count (u32) and an (N, 7) float32
array (position, orientation w x y z). Frames with the same count as the previous one are
stored XOR'ed with it as raw bits: resting bodies give long runs of zero bytes, which zlib
squeezes, and the encoding is lossless, so a replay can be compared bit for bit.

Replay depends on determinism: with a fixed scene, solver and arch, CPU runs are bitwise
repeatable (no float atomics in the state; see solvers/mass_splitting.py). A setting the header
lacks (one added after the recording was made) replays at its default, and the physics it
changes shows as a departure: a recording below 8 iterations made before ``Settings.step_sweeps``
reached its schedule (2026-11-28: first the Jacobi family, then every schedule) departs once its
contacts are swept. A setting's former name reads as its new one (settings.RENAMED).
"""

from __future__ import annotations

import dataclasses
import json
import struct
import tomllib
import zlib
from pathlib import Path

import numpy as np

from .errors import SandboxError

MAGIC = b"SBXREC"
VERSION = 1


def _encode(obj):
    if dataclasses.is_dataclass(obj):
        return {"__type__": type(obj).__name__, **{f.name: _encode(getattr(obj, f.name))
                                                    for f in dataclasses.fields(obj)}}
    if isinstance(obj, np.ndarray):
        return {"__ndarray__": obj.tolist(), "dtype": str(obj.dtype)}
    if isinstance(obj, (list, tuple)):
        return [_encode(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _encode(v) for k, v in obj.items()}
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    return obj


def _decode(obj):
    from .scene import spec

    if isinstance(obj, list):
        return [_decode(v) for v in obj]
    if isinstance(obj, dict):
        if "__ndarray__" in obj:
            return np.asarray(obj["__ndarray__"], dtype=obj["dtype"])
        if "__type__" in obj:
            cls = getattr(spec, obj["__type__"])
            return cls(**{k: _decode(v) for k, v in obj.items() if k != "__type__"})
        return {k: _decode(v) for k, v in obj.items()}
    return obj


def _frame(world) -> np.ndarray:
    """What a recording stores of a step: (N, 7) float32, position then orientation (w x y z)."""
    st = world.state(("position", "orientation"))
    return np.concatenate([st["position"], st["orientation"]], axis=1).astype(np.float32)


def _apply_due(world, events: list) -> None:
    """Apply (and pop) the logged (step, event) pairs due at the world's current step."""
    while events and events[0][0] <= world.step_count:
        world.apply_event(events.pop(0)[1])


class Recorder:
    """Collects frames of a world; ``save`` writes the file. ``scene_path`` is the TOML the
    world was loaded from (its text is stored, so the recording stands alone)."""

    def __init__(self, world, scene_path):
        self.world = world
        self.scene_path = Path(scene_path).resolve()
        self.scene_text = self.scene_path.read_text(encoding="utf-8")
        self.settings = dataclasses.asdict(world.initial_settings)  # later changes are in the event log
        self.start_solver = world.initial_solver  # solver changes since step 0 are in the event log
        self.start_step = world.step_count
        self.start_events = len(world.applied_events)  # events already in frame 0
        self._frames = []
        self.capture()

    @property
    def frame_count(self) -> int:
        return len(self._frames)

    def capture(self) -> None:
        self._frames.append(_frame(self.world))

    def save(self, path) -> int:
        """Write the recording to ``path``; its size in bytes. A path that cannot be written raises
        SandboxError and keeps the frames, so a second ``save`` elsewhere loses nothing."""
        header = {
            "version": VERSION,
            "scene_path": str(self.scene_path),
            "scene_text": self.scene_text,
            "settings": self.settings,
            "solver": self.start_solver[0],
            "iterations": self.start_solver[1],
            "solver_options": self.start_solver[2],
            "reserve_pieces": self.world.reserve[0],
            "reserve_kinds": list(self.world.reserve[1]),
            "arch": self.world.arch,
            "start_step": self.start_step,
            "start_events": self.start_events,
            "frames": len(self._frames),
            "events": [[step, _encode(event)] for step, event in self.world.applied_events],
        }
        payload = zlib.compressobj(6)
        chunks = []
        prev = None
        for frame in self._frames:
            bits = frame.view(np.uint32)
            data = bits ^ prev if prev is not None and prev.shape == bits.shape else bits
            chunks.append(payload.compress(struct.pack("<I", len(frame)) + data.tobytes()))
            prev = bits
        chunks.append(payload.flush())
        head = json.dumps(header).encode("utf-8")
        blob = MAGIC + struct.pack("<HI", VERSION, len(head)) + head + b"".join(chunks)
        try:
            Path(path).write_bytes(blob)
        except OSError as exc:
            raise SandboxError(f"recording {path}: cannot write it ({exc.strerror})") from None
        return len(blob)


def load(path) -> tuple[dict, list[np.ndarray]]:
    """Read a recording: (header, frames). Raises SandboxError for anything unreadable."""
    path = Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise SandboxError(f"recording {path}: cannot read it ({exc.strerror})") from None
    if not blob.startswith(MAGIC) or len(blob) < len(MAGIC) + 6:
        raise SandboxError(f"recording {path}: not a sandbox recording (bad magic)")
    version, head_len = struct.unpack_from("<HI", blob, len(MAGIC))
    if version != VERSION:
        raise SandboxError(f"recording {path}: format version {version}, this sandbox reads version {VERSION}")
    start = len(MAGIC) + 6
    try:
        header = json.loads(blob[start:start + head_len].decode("utf-8"))
        raw = zlib.decompress(blob[start + head_len:])
    except (ValueError, zlib.error) as exc:
        raise SandboxError(f"recording {path}: damaged ({exc})") from None
    frames, prev, pos = [], None, 0
    while pos < len(raw):
        (n,) = struct.unpack_from("<I", raw, pos)
        pos += 4
        bits = np.frombuffer(raw, dtype=np.uint32, count=n * 7, offset=pos).reshape(n, 7)
        pos += n * 7 * 4
        if prev is not None and prev.shape == bits.shape:
            bits = bits ^ prev
        frames.append(bits.view(np.float32))
        prev = bits
    if len(frames) != header.get("frames"):
        raise SandboxError(f"recording {path}: damaged (header says {header.get('frames')} frames, found {len(frames)})")
    return header, frames


def replay(path, arch: str = "cpu", on_frame=None) -> dict:
    """Re-simulate a recording and compare every frame bit for bit.

    Returns {"frames", "first_departure" (None when identical), "max_difference"}.
    ``on_frame(step, world)`` is called after each re-simulated frame (for viewers)."""
    from .world import World
    from .scene.loader import scene_from_dict
    from .settings import Settings

    header, frames = load(path)
    try:
        data = tomllib.loads(header["scene_text"])
    except tomllib.TOMLDecodeError as exc:
        raise SandboxError(f"recording {path}: stored scene does not parse ({exc})") from None
    scene_path = Path(header["scene_path"])
    scene = scene_from_dict(data, source=str(scene_path), base_dir=scene_path.parent)
    try:
        settings = Settings().replace(**header["settings"])
    except SandboxError as exc:
        raise SandboxError(f"recording {path}: {exc}") from None
    world = World(scene, solver=header["solver"], iterations=header["iterations"], arch=arch,
                  settings=settings, reserve_pieces=header.get("reserve_pieces", 0),
                  reserve_kinds=tuple(header.get("reserve_kinds", ())),
                  **{k: v for k, v in header["solver_options"].items() if v is not None})
    world._pending = []  # the recorded log already holds the scripted events
    world.auto_fracture = False  # ... and the impact fractures
    events = [(step, _decode(e)) for step, e in header["events"]]
    # A recording started mid-run (the web sandbox's Record button) holds every event since
    # step 0: re-simulate up to its first frame, which determinism makes exact.
    before_start = events[: header.get("start_events", 0)]
    events = events[len(before_start):]
    while world.step_count < header["start_step"]:
        _apply_due(world, before_start)
        world.step(1)
    _apply_due(world, before_start)  # the events logged at the first frame's step
    first, worst = None, 0.0
    for k, recorded in enumerate(frames):
        if k > 0:
            _apply_due(world, events)
            world.step(1)
        now = _frame(world)
        if now.shape != recorded.shape:
            first = k if first is None else first
            worst = np.inf
        else:
            diff = float(np.abs(now.astype(np.float64) - recorded).max()) if len(now) else 0.0
            if (now.view(np.uint32) != recorded.view(np.uint32)).any() and first is None:
                first = k
            worst = max(worst, diff)
        if on_frame is not None:
            on_frame(k, world)
    return {"frames": len(frames), "first_departure": first, "max_difference": worst}
