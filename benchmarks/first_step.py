"""Time to the first step of every shipped scene, as a new user meets it: a fresh process that
imports the package, loads the scene, builds the world and runs one step.

    python benchmarks/first_step.py [--scenes stack_20,confined_pile] [--solver <the scene's>]
                                    [--cache warm|fresh|both] [--split [--instances N]]

``warm``: Taichi's offline kernel cache as the previous runs left it (the scene is run once
untimed first, so the cache holds its kernels); ``fresh``: an empty cache directory
(``TI_OFFLINE_CACHE_FILE_PATH``), as on a newly installed machine. Each figure is the wall
time of the whole child process, interpreter start-up included, and its split: import, world
build (scene parsing, buffers, upload) and the first step (compiling or loading its kernels).

``--split`` also says where the build and the first step go, by wrapping two methods of Taichi
1.7's ``Kernel`` in the child (a diagnostic, not engine code): *frontend*, Taichi's Python AST
transform of each new kernel instance (``Kernel.materialize``), which Taichi 1.7 runs in every
process because its offline cache is keyed on the IR the frontend produces; and *kernels*, the
first launch of each instance less its frontend (the offline cache's load, or a compile, and
LLVM's JIT of the module to machine code). The rest is the sandbox's own Python and the runs.
``--instances N`` lists the N costliest instances by name: a small instance's first launch costs
~15 ms however little it does (docs/bench.md, "Eleventh pass"), so their number matters too.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
split = {"frontend": 0.0, "kernels": 0.0, "instances": 0, "each": {}}
if sys.argv[3] == "split":
    from taichi.lang import kernel_impl

    def timed_materialize(self, *args, _inner=kernel_impl.Kernel.materialize, **kwargs):
        before, t = len(self.compiled_kernels), time.perf_counter()
        out = _inner(self, *args, **kwargs)
        if len(self.compiled_kernels) > before:  # a new instance: the frontend ran
            split["frontend"] += time.perf_counter() - t
            split["instances"] += 1
            split["each"][f"{self.func.__name__}#{len(self.compiled_kernels)}"] = [time.perf_counter() - t, 0.0]
        return out

    def timed_call(self, *args, _inner=kernel_impl.Kernel.__call__, **kwargs):
        before, front, t = len(self.compiled_kernels), split["frontend"], time.perf_counter()
        out = _inner(self, *args, **kwargs)
        if len(self.compiled_kernels) > before:  # its first launch: cache load or compile, and JIT
            launch = time.perf_counter() - t - (split["frontend"] - front)
            split["kernels"] += launch
            split["each"][f"{self.func.__name__}#{len(self.compiled_kernels)}"][1] = launch
        return out

    kernel_impl.Kernel.materialize = timed_materialize
    kernel_impl.Kernel.__call__ = timed_call
from sandbox import Scene, World
from sandbox.scene.library import resolve_scene
t1 = time.perf_counter()
scene = Scene.load(resolve_scene(sys.argv[1]))
kw = {"solver": sys.argv[2]} if sys.argv[2] else {}
world = World(scene, arch="cpu", **kw)
t2 = time.perf_counter()
world.step(1)
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "build": t2 - t1, "step": t3 - t2, **split}))
"""

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def run_child(scene: str, solver: str, cache_dir: str | None, split: bool = False) -> dict:
    env = dict(os.environ, TI_SKIP_VERSION_CHECK="ON")
    if cache_dir is not None:
        env["TI_OFFLINE_CACHE_FILE_PATH"] = cache_dir
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CHILD, scene, solver, "split" if split else ""], env=env,
                         capture_output=True, text=True)
    wall = time.perf_counter() - t
    if out.returncode != 0:
        raise SystemExit(f"{scene}: the child failed:\n{out.stderr[-2000:]}")
    split = json.loads(out.stdout.strip().splitlines()[-1])
    return dict(split, wall=wall)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default=",".join(sorted(p.stem for p in SCENES.glob("*.toml"))))
    ap.add_argument("--solver", default="", help="default: each scene's own")
    ap.add_argument("--cache", choices=("warm", "fresh", "both"), default="warm")
    ap.add_argument("--split", action="store_true", help="say how much of build + first step is Taichi's "
                    "frontend and how much the kernels' first launches (module docstring)")
    ap.add_argument("--instances", type=int, default=0, metavar="N",
                    help="with --split: also list the N costliest kernel instances (frontend + first launch)")
    a = ap.parse_args()
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
          "seconds of a fresh process: wall (import / build / first step" + ("; of build + first step: Taichi's "
          "frontend, the kernels' first launches, kernel instances)" if a.split else ")"))

    def figures(r: dict) -> str:
        text = f"{r['wall']:6.1f} s ({r['import']:.1f} / {r['build']:.1f} / {r['step']:.1f}"
        if a.split:
            text += f"; {r['frontend']:.1f} / {r['kernels']:.1f} / {r['instances']}"
        return text + ")"

    for scene in a.scenes.split(","):
        row = f"{scene:22s}"
        runs = []
        if a.cache in ("warm", "both"):
            run_child(scene, a.solver, None)  # fill the cache
            runs.append(("warm", run_child(scene, a.solver, None, a.split)))
        if a.cache in ("fresh", "both"):
            with tempfile.TemporaryDirectory() as empty:
                runs.append(("fresh", run_child(scene, a.solver, empty, a.split)))
        print(row + "".join(f"  {cache} {figures(r)}" for cache, r in runs), flush=True)
        for cache, r in runs if a.split and a.instances else ():
            costliest = sorted(r["each"].items(), key=lambda kv: -sum(kv[1]))[:a.instances]
            for name, (front, launch) in costliest:  # name#k: the kernel's k-th instance in the process
                print(f"    {cache} {name:32s} frontend {front:6.3f} s  first launch {launch:6.3f} s")


if __name__ == "__main__":
    main()
