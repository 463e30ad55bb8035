"""Our solvers beside the peer engines on the same scene, same dt and iteration count, in one run.

    pip install -e ".[peers]"
    python benchmarks/peer_speed.py [--scene pile_1000] [--iterations 15] [--settle 300]
                                    [--steps 20] [--rounds 7] [--solvers pgs,mass-splitting,block-mass-splitting]
                                    [--peers pybullet,rapier-t1,rapier-t2]

The peers are ``sandbox/peers.py``'s: pybullet 3.2.7 (``numSolverIterations`` = iterations, one
thread) and Rapier 0.36 (``num_solver_iterations`` = iterations: our scheme, one substep per
iteration with a biased and a relax sweep) with one and with two worker threads; every pair
gets friction 0.5, no damping, no sleeping. Every engine settles ``--settle`` steps (0: time the
fall from the scene's start); then, ``--rounds`` times, each engine in turn runs ``--steps``
timed steps (our step includes collision, as the peers' steps do). The CPU speed of a shared VM
drifts by 1.5x within minutes, so the engines are interleaved round by round and each round
gives a ratio; printed are the median steps/s of each engine, the median and range of the
per-round ratios to the ``--against`` engine, and the mean kinetic energy of 60 steps after the
timing (the jitter measure), computed the same way for all. Only box-and-plane scenes are
translated.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from sandbox import Scene, World
from sandbox.cpu_workers import cpu_threads
from sandbox.peers import PEERS
from sandbox.scene.library import resolve_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=300)
    ap.add_argument("--steps", type=int, default=20, help="timed steps per engine and round")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--solvers", default="pgs,mass-splitting,block-mass-splitting")
    ap.add_argument("--peers", default="pybullet,rapier-t1,rapier-t2")
    ap.add_argument("--against", default="rapier-t2", help="the engine the ratios are taken to")
    a = ap.parse_args()
    import taichi as ti

    scene = Scene.load(resolve_scene(a.scene))
    engines, worlds = {}, {}
    for name in a.peers.split(","):
        peer = PEERS[name]
        ok, why = peer.available()
        if not ok:
            raise SystemExit(f"{name}: {why}")
        label = f"{name} {peer.version()}"
        worlds[label] = peer.open(scene, a.iterations)
        engines[label] = (lambda w: lambda n: [w.step() for _ in range(n)])(worlds[label])
    for solver in a.solvers.split(","):
        warm_up = World(scene, solver=solver, iterations=a.iterations, arch="cpu")
        warm_up.step(1)  # compiles the kernels outside the timed rounds, also with --settle 0
        warm_up.close()
        world = World(scene, solver=solver, iterations=a.iterations, arch="cpu")
        worlds[solver] = world

        def run(n, world=world):
            world.step(n)
            ti.sync()

        engines[solver] = run
    against = next((label for label in engines if label.split(" ")[0] == a.against), next(iter(engines)))
    for run in engines.values():
        run(a.settle)
    rates = {name: [] for name in engines}
    for _ in range(a.rounds):
        for name, run in engines.items():
            t = time.perf_counter()
            run(a.steps)
            rates[name].append(a.steps / (time.perf_counter() - t))
    ke = {name: [] for name in engines}
    for _ in range(60):
        for name, world in worlds.items():
            if isinstance(world, World):
                world.step(1)
                ke[name].append(world.metrics()["kinetic_energy"])
            else:
                world.step()
                ke[name].append(world.kinetic_energy())
    print(f"# {platform.processor() or platform.machine()}, {a.scene}, {a.iterations} iterations, "
          f"settle {a.settle}, {a.rounds} rounds of {a.steps} timed steps per engine, interleaved; "
          f"ours on {cpu_threads()} Taichi CPU threads, pybullet on 1, rapier-tN on N")
    base = np.asarray(rates[against])
    for name in engines:
        r = np.asarray(rates[name])
        line = f"{name:24s} {np.median(r):8.1f} steps/s   KE(60 steps) {np.mean(ke[name]):.3e} J"
        if name != against:
            ratio = r / base
            line += (f"   ratio to {against}: median {np.median(ratio):.2f}x "
                     f"(rounds {ratio.min():.2f}-{ratio.max():.2f}x)")
        print(line, flush=True)
    for world in worlds.values():
        world.close()


if __name__ == "__main__":
    main()
