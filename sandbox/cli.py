"""The ``sandbox`` command: ``run`` a scene headless (optionally recording it), ``replay`` a
recording, list the shipped ``scenes``."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

SCENES_DIR = Path(__file__).resolve().parent.parent / "scenes"


def _resolve_scene(name: str) -> Path:
    p = Path(name)
    if p.exists():
        return p
    for candidate in (SCENES_DIR / name, SCENES_DIR / f"{name}.toml"):
        if candidate.exists():
            return candidate
    from .errors import SandboxError

    known = ", ".join(sorted(q.stem for q in SCENES_DIR.glob("*.toml")))
    raise SandboxError(f"no scene file {name!r} (and no shipped scene of that name; shipped: {known})")


def cmd_run(args) -> int:
    from tqdm import tqdm

    from . import Scene, World

    path = _resolve_scene(args.scene)
    scene = Scene.load(path)
    options = {}
    if args.shuffle:
        options["shuffle"] = True
    t0 = time.perf_counter()
    world = World(scene, solver=args.solver, iterations=args.iterations, arch=args.arch, profile=True, **options)
    if args.record:
        world.step(0)
    else:
        world.step(1)  # compile every kernel before timing (a recording starts at step 0)
    world.profiler.reset()
    build_s = time.perf_counter() - t0
    steps = args.steps
    series = {"kinetic_energy": [], "max_penetration": [], "contacts": []}
    recorder = None
    if args.record:
        from .recording import Recorder

        recorder = Recorder(world, path)
    wall = 0.0
    for _ in tqdm(range(steps), desc=f"{path.stem} / {world.solver}", unit="step", disable=args.quiet):
        t = time.perf_counter()
        world.step(1)
        wall += time.perf_counter() - t
        if recorder is not None:
            recorder.capture()
        m = world.metrics()
        for k in series:
            series[k].append(m[k])
    m = world.metrics()
    timing = world.timing_ms()
    report = {
        "scene": str(path),
        "solver": world.solver,
        "solver_options": world.solver_options,
        "iterations": world.iterations,
        "dt": world.dt,
        "substeps": world.substeps,
        "steps": steps,
        "arch": world.arch,
        "bodies": world.body_count,
        "contacts": m["contacts"],
        "timing_ms": {k: timing[k] for k in ("collide", "solve", "integrate", "total")},
        "timing_ms_by_stage": timing,
        "steps_per_second": steps / wall if wall > 0 else float("inf"),
        "build_and_compile_s": build_s,
        "final": m,
        "series": series,
    }
    print(f"scene      {path}  ({world.body_count} bodies, arch {world.arch})")
    print(f"solver     {world.solver}, {world.iterations} iterations, dt {world.dt:.5f} s x {steps} steps")
    print(f"contacts   {m['contacts']} points in {m['manifolds']} manifolds")
    print(f"energy     kinetic {m['kinetic_energy']:.3e} J   penetration max {1e3 * m['max_penetration']:.2f} mm,"
          f" mean {1e3 * m['mean_penetration']:.2f} mm")
    print(f"residual   rms {m['residual_rms']:.2e} m/s, max {m['residual_max']:.2e} m/s")
    print("ms/step    " + "  ".join(f"{k} {timing[k]:.2f}" for k in ("collide", "solve", "integrate", "total"))
          + f"   ->  {report['steps_per_second']:.1f} steps/s (wall, incl. Python)")
    if args.report:
        Path(args.report).write_text(json.dumps(report, indent=1))
        print(f"report     {args.report}")
    if recorder is not None:
        size = recorder.save(args.record)
        print(f"recording  {args.record}: {len(recorder._frames)} frames, {size / 1e6:.2f} MB")
    return 0


def cmd_replay(args) -> int:
    from .recording import replay

    result = replay(args.file, arch=args.arch)
    if result["first_departure"] is None:
        print(f"replay     {args.file}: {result['frames']} frames identical bit for bit")
        return 0
    print(f"replay     {args.file}: departs from the recording at frame {result['first_departure']} "
          f"(max difference {result['max_difference']:.3g})")
    return 1


def cmd_scenes(args) -> int:
    from .scene.loader import load_scene

    for path in sorted(SCENES_DIR.glob("*.toml")):
        try:
            desc = load_scene(path).description.strip().splitlines()
        except Exception as exc:  # listing must not die on one bad file
            desc = [f"(does not load: {exc})"]
        print(f"{path.stem:28s} {desc[0] if desc else ''}")
    return 0


def main(argv=None) -> int:
    from .errors import SandboxError
    from .solvers import SOLVERS

    parser = argparse.ArgumentParser(prog="sandbox", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="simulate a scene headless and summarise it")
    run.add_argument("scene", help="a scene file, or the name of a shipped scene (see `sandbox scenes`)")
    run.add_argument("--solver", choices=list(SOLVERS), default=None, help="default: the scene's")
    run.add_argument("--iterations", type=int, default=None, help="default: the scene's")
    run.add_argument("--steps", type=int, default=600)
    run.add_argument("--arch", choices=["cpu", "cuda", "auto"], default="auto")
    run.add_argument("--shuffle", action="store_true", help="pgs-colored: permute contacts and colours every step")
    run.add_argument("--report", metavar="FILE.json", help="write a JSON report with timings and per-step series")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--record", metavar="FILE", help="record scene, settings, events and every frame's transforms")
    run.set_defaults(func=cmd_run)
    rep = sub.add_parser("replay", help="re-simulate a recording and report where it departs, if anywhere")
    rep.add_argument("file")
    rep.add_argument("--arch", choices=["cpu", "cuda"], default="cpu")
    rep.set_defaults(func=cmd_replay)
    scenes = sub.add_parser("scenes", help="list the shipped scenes")
    scenes.set_defaults(func=cmd_scenes)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except SandboxError as exc:
        print(f"sandbox: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
