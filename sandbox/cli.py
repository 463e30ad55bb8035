"""The ``sandbox`` command (also ``python -m sandbox``): ``run`` a scene headless (optionally
recording it), ``replay`` a recording, list the shipped ``scenes``, ``bench`` the solvers;
``serve`` (the web sandbox) comes from the ``web`` package as a plugin."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from .errors import SandboxError

ARCHES = ("cpu", "cuda", "auto")


def whole_number(minimum: int):
    """An argparse type: a whole number of at least ``minimum`` (refused before Taichi starts)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number >= {minimum}, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be a whole number >= {minimum}, got {value}")
        return value

    return parse


def check_writable(path: str, what: str) -> None:
    """Refuse an output file whose folder is missing or is not a folder, before any simulating: a run
    that ends by failing to write what it was asked for has lost its time."""
    folder = Path(path).resolve().parent
    if not folder.is_dir():
        raise SandboxError(f"{what} {path}: cannot write it (no folder {folder})")
    if Path(path).is_dir():
        raise SandboxError(f"{what} {path}: cannot write it (it is a folder)")


def cmd_run(args) -> int:
    from tqdm import tqdm

    from . import Scene
    from .scene import resolve_scene

    path = resolve_scene(args.scene)
    scene = Scene.load(path)  # a bad scene is refused before Taichi starts (and prints its banner)
    for output, what in ((args.report, "report"), (args.record, "recording")):
        if output:
            check_writable(output, what)
    from . import World
    for warning in scene.warnings:
        print(f"warning    {warning}")
    options = {}
    if args.shuffle:
        options["shuffle"] = True
    t0 = time.perf_counter()
    world = World(scene, solver=args.solver, iterations=args.iterations, arch=args.arch, profile=True,
                  formulation=args.formulation, **options)
    if args.record:
        world.step(0)
    else:
        world.step(1)  # compile every kernel before timing (a recording starts at step 0)
    world.profiler.reset()
    build_s = time.perf_counter() - t0
    steps = args.steps
    series = {"kinetic_energy": [], "max_penetration": [], "contacts": [], "awake_bodies": []}
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
        "formulation": world.formulation,
        "effects": list(world.effects),
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
    print(f"solver     {world.solver}, {world.iterations} iterations ({world.formulation}), dt {world.dt:.5f} s x {steps} steps")
    print(f"contacts   {m['contacts']} points in {m['manifolds']} manifolds")
    dynamic = m["awake_bodies"] + m["sleeping_bodies"]
    print(f"islands    {m['islands']}; {m['awake_bodies']} of {dynamic} dynamic bodies awake, "
          f"{m['sleeping_bodies']} asleep" + ("" if world.sleeping else " (no sleeping effect)"))
    print(f"energy     kinetic {m['kinetic_energy']:.3e} J   penetration max {1e3 * m['max_penetration']:.2f} mm,"
          f" mean {1e3 * m['mean_penetration']:.2f} mm")
    print(f"residual   rms {m['residual_rms']:.2e} m/s, max {m['residual_max']:.2e} m/s")
    print("ms/step    " + "  ".join(f"{k} {timing[k]:.2f}" for k in ("collide", "solve", "integrate", "total"))
          + f"   ->  {report['steps_per_second']:.1f} steps/s (wall, incl. Python)")
    if args.report:
        try:
            Path(args.report).write_text(json.dumps(report, indent=1))
        except OSError as exc:
            raise SandboxError(f"report {args.report}: cannot write it ({exc.strerror})") from None
        print(f"report     {args.report}")
    for failure in world.fracture_failures:
        print(f"fracture   {failure}")
    if recorder is not None:
        size = recorder.save(args.record)
        print(f"recording  {args.record}: {recorder.frame_count} frames, {size / 1e6:.2f} MB")
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
    from .scene import load_scene, shipped_scenes

    for path in shipped_scenes():
        try:
            desc = load_scene(path).description.strip().splitlines()
        except Exception as exc:  # listing must not die on one bad file
            desc = [f"(does not load: {exc})"]
        print(f"{path.stem:28s} {desc[0] if desc else ''}")
    return 0


def cmd_bench(args) -> int:
    from .bench import run

    def ints(text, what):
        try:
            return [int(x) for x in text.split(",") if x.strip()] if text else None
        except ValueError:
            raise SandboxError(f"{what} must be comma-separated integers, got {text!r}") from None

    run(scenes=args.scenes or None, solvers=args.solvers.split(",") if args.solvers else None,
        iterations=ints(args.iterations, "--iterations"), arch=args.arch, out=args.out, quick=args.quick,
        settle=args.settle, window=args.window, steps=args.steps,
        scaling_sizes=ints(args.scaling_sizes, "--scaling-sizes"), scaling_iterations=args.scaling_iterations,
        shuffle=args.shuffle, peers=not args.no_peers, scaling=not args.no_scaling, quiet=args.quiet)
    return 0


def _register_plugins(sub) -> None:
    """Commands from other installed packages (the web sandbox's ``serve``): each entry point of
    the group ``sandbox.commands`` is a function that adds its subparser. The engine never
    imports them by name."""
    from importlib.metadata import entry_points

    for ep in sorted(entry_points(group="sandbox.commands"), key=lambda e: e.name):
        ep.load()(sub)


def _add_arch(parser, default: str, choices=ARCHES) -> None:
    parser.add_argument("--arch", choices=list(choices), default=default, help=f"Taichi backend (default: {default})")


def _add_run_flags(parser, arch_default: str) -> None:
    """The flags ``run`` and ``bench`` share: --arch, --shuffle, --quiet."""
    from .solvers import SOLVERS

    shufflers = ", ".join(name for name, info in SOLVERS.items() if "shuffle" in info.defaults)
    _add_arch(parser, arch_default)
    parser.add_argument("--shuffle", action="store_true",
                        help=f"permute contacts and colours every step (solvers that take it: {shufflers})")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def main(argv=None) -> int:
    from .settings import FORMULATIONS
    from .solvers import SOLVERS

    parser = argparse.ArgumentParser(prog="sandbox", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="simulate a scene headless and summarise it")
    run.add_argument("scene", help="a scene file, or the name of a shipped scene (see `sandbox scenes`)")
    run.add_argument("--solver", choices=list(SOLVERS), default=None, help="default: the scene's")
    run.add_argument("--iterations", type=whole_number(1), default=None, help="default: the scene's")
    run.add_argument("--steps", type=whole_number(1), default=600)
    run.add_argument("--formulation", choices=list(FORMULATIONS), default=None,
                     help="soft-step (Box2D v3, the default) or paper (Tonge et al.: one step, Baumgarte); "
                     "default: the scene's")
    _add_run_flags(run, arch_default="auto")
    run.add_argument("--report", metavar="FILE.json", help="write a JSON report with timings and per-step series")
    run.add_argument("--record", metavar="FILE", help="record scene, settings, events and every frame's transforms")
    run.set_defaults(func=cmd_run)
    rep = sub.add_parser("replay", help="re-simulate a recording and report where it departs, if anywhere")
    rep.add_argument("file")
    _add_arch(rep, "cpu", choices=("cpu", "cuda"))
    rep.set_defaults(func=cmd_replay)
    bench = sub.add_parser("bench", help="error vs cost per scene x solver x iteration count, scaling, pybullet peer",
                           description="Settle each scene, then measure error (residual, penetration, resting kinetic "
                           "energy, marker drift) and cost (ms/step by stage, ms/iteration, steps/s); write "
                           "bench.csv, bench.json, scaling.csv and PNG plots. See docs/bench.md.")
    bench.add_argument("scenes", nargs="*", help="scene files or shipped scene names (default: stack_20 pyramid_20 "
                       "pile_1000; --quick: pyramid_20)")
    bench.add_argument("--solvers", help="comma-separated (default: all; --quick: pgs,mass-splitting)")
    bench.add_argument("--iterations", help="comma-separated counts (default: 1,2,4,8,15,30,60,120,250,500; "
                       "--quick: 1,4,16)")
    _add_run_flags(bench, arch_default="cpu")
    bench.add_argument("--out", default="out/bench", help="output directory (default: out/bench)")
    bench.add_argument("--quick", action="store_true", help="small smoke run of every output (budget: 2 min on 2 cores)")
    bench.add_argument("--settle", type=whole_number(0), help="frames before measuring (default 120; --quick 60)")
    bench.add_argument("--window", type=whole_number(1), help="frames of the error window (default 60; --quick 30)")
    bench.add_argument("--steps", type=whole_number(1), help="timed steps, once per-stage and once whole (default 60; --quick 30)")
    bench.add_argument("--scaling-sizes", help="grid pile sizes in bodies (default: 100,300,1000,2000,5000; "
                       "--quick: 32,100)")
    bench.add_argument("--scaling-iterations", type=whole_number(1), help="iterations in the scaling runs (default 15; --quick 4)")
    bench.add_argument("--no-scaling", action="store_true", help="skip the scaling piles")
    bench.add_argument("--no-peers", action="store_true", help="skip pybullet even when importable")
    bench.set_defaults(func=cmd_bench)
    scenes = sub.add_parser("scenes", help="list the shipped scenes")
    scenes.set_defaults(func=cmd_scenes)
    _register_plugins(sub)
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except SandboxError as exc:
        print(f"sandbox: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
