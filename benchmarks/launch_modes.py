"""The same world stepped with each iteration launch mode, interleaved, from one settled state.

    python benchmarks/launch_modes.py [--solver mass-splitting] [--scene pile_1000]
                                      [--modes per-stage,one,per-substep] [--settle 300]

All launch modes compute the same bits (solvers/substep.py), so switching
``Settings.iteration_launch`` between timed blocks of one world compares launch cost
only, on the same contacts. Prints the median and best ms/step of 4 blocks of 10 steps.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sandbox import Scene, World
from sandbox.scene.library import resolve_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--solver", default="mass-splitting")
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--modes", default="per-stage,one,per-substep")
    ap.add_argument("--settle", type=int, default=300)
    a = ap.parse_args()
    import taichi as ti

    modes = a.modes.split(",")
    world = World(Scene.load(resolve_scene(a.scene)), solver=a.solver, iterations=a.iterations, arch="cpu")
    world.step(a.settle)
    for m in modes:  # compile every mode outside the timings
        world.settings = world.settings.replace(iteration_launch=m)
        world.step(1)
    times = {m: [] for m in modes}
    for _ in range(4):
        for m in modes:
            world.settings = world.settings.replace(iteration_launch=m)
            ti.sync()
            t = time.perf_counter()
            world.step(10)
            ti.sync()
            times[m].append((time.perf_counter() - t) / 10)
    for m in modes:
        print(f"{a.scene} {a.solver:22s} {m:12s} median {1e3 * np.median(times[m]):7.2f} ms/step   "
              f"best {1e3 * min(times[m]):7.2f}")


if __name__ == "__main__":
    main()
