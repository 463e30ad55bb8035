"""Sleeping's speed-up on the settled pile (issue 16): one process, the same scene twice.

    PYTHONPATH=$PWD python benchmarks/sleep_pile.py [--scene pile_1000] [--settle 900] [--steps 60]
                                                    [--solver NAME] [--arch cpu]

The scene runs in two worlds, one with the ``sleeping`` effect (``World.set_effects``) and one
without. Both settle for ``--settle`` steps (compiling on their first steps), then each runs
``--steps`` further steps, timed as a whole from Python (``World.step``, synchronised: the
kernels' launches are waited for), in alternating blocks of ten so that a change of the
machine's load hits both alike; a third series wakes a small island before each of the
sleeping world's blocks (the rest stays asleep). Prints the share of bodies asleep, the mean ms
per step, the ratios, and the load average: the machine may be shared, so the figure is one
run's.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import taichi as ti

from sandbox import Scene, World, resolve_scene

BLOCK = 10


def _timed(world: World, steps: int) -> float:
    ti.sync()
    t0 = time.perf_counter()
    world.step(steps)
    ti.sync()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--settle", type=int, default=900)
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--solver", default=None, help="default: the scene's")
    ap.add_argument("--arch", default="cpu")
    args = ap.parse_args()
    scene = Scene.load(resolve_scene(args.scene))
    worlds = {}
    for name, sleeping in (("sleeping", True), ("awake", False)):
        world = World(scene, solver=args.solver, arch=args.arch)
        effects = [e for e in world.effects if e != "sleeping"] + (["sleeping"] if sleeping else [])
        world.set_effects(effects)
        t0 = time.perf_counter()
        world.step(args.settle)
        print(f"{name:9s} settled {args.settle} steps in {time.perf_counter() - t0:.1f} s (compile included)")
        worlds[name] = world
    settled = worlds["sleeping"].metrics()
    seconds = {name: 0.0 for name in (*worlds, "one island")}
    woken = []
    labels = worlds["sleeping"].island_labels()
    roots, sizes = np.unique(labels[labels >= 0], return_counts=True)
    small = np.where(sizes <= 0.05 * len(labels), sizes, 0)  # islands of at most 5 % of the bodies
    target = int(roots[np.argmax(small)] if small.any() else roots[np.argmin(sizes)])  # the largest of them
    for _ in range(0, args.steps, BLOCK):
        for name, world in worlds.items():
            seconds[name] += _timed(world, BLOCK)
        sleeper = worlds["sleeping"]
        sleeper.wake([target])  # a small island wakes and stays awake through the block (sleep_time)
        seconds["one island"] += _timed(sleeper, BLOCK)
        woken.append(sleeper.metrics()["awake_bodies"])
        sleeper.step(int(round(sleeper.settings.sleep_time / sleeper.dt)) + 2)  # untimed: asleep again
    steps = BLOCK * ((args.steps + BLOCK - 1) // BLOCK)
    m = worlds["sleeping"].metrics()
    bodies = m["awake_bodies"] + m["sleeping_bodies"]
    asleep_share = m["sleeping_bodies"] / bodies if bodies else 0.0
    ms = {name: 1e3 * s / steps for name, s in seconds.items()}
    load = os.getloadavg()
    print(f"scene      {args.scene} ({bodies} dynamic bodies), solver {worlds['awake'].solver} x "
          f"{worlds['awake'].iterations}, arch {worlds['awake'].arch}, {os.cpu_count()} CPUs")
    print(f"asleep     {settled['sleeping_bodies']} of {bodies} bodies after {args.settle} steps "
          f"({100 * settled['sleeping_bodies'] / max(bodies, 1):.1f} %, {settled['islands']} islands); "
          f"{m['sleeping_bodies']} ({100 * asleep_share:.1f} %) after {args.settle + steps}")
    print(f"ms/step    sleeping {ms['sleeping']:.3f}   awake {ms['awake']:.3f}   over {steps} steps each")
    print(f"ratio      {100 * ms['sleeping'] / ms['awake']:.1f} % of the awake world's time per step")
    print(f"one island awake ({min(woken)}-{max(woken)} bodies, the rest asleep): {ms['one island']:.3f} ms/step, "
          f"{100 * ms['one island'] / ms['awake']:.1f} % of the awake world's")
    print(f"load avg   {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (1, 5, 15 min)")


if __name__ == "__main__":
    main()
