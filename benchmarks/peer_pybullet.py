"""Our solvers and pybullet on the same scene, same dt and iteration count, in one run.

    pip install -e ".[peers]"
    python benchmarks/peer_pybullet.py [--scene pile_1000] [--iterations 15] [--settle 300]
                                       [--steps 20] [--rounds 7]
                                       [--solvers pgs,mass-splitting,block-mass-splitting]

pybullet is set up as the anchors in the team's RESULTS.md were: boxes as maximal-coordinate
rigid bodies with the scene's masses and half extents, a static plane, friction sqrt(0.5) per
body (Bullet multiplies the two coefficients, so every pair gets 0.5), no damping, no sleeping,
``numSolverIterations`` = iterations. Every engine settles ``--settle`` steps; then, ``--rounds``
times, each engine in turn runs ``--steps`` timed steps (our step includes collision, as
``stepSimulation`` does). The CPU speed of a shared VM drifts by 1.5x within minutes, so the
engines are interleaved round by round and each round gives a ratio; printed are the median
steps/s of each engine, the median and range of the per-round ratios, and the mean kinetic
energy of 60 steps after the timing (the jitter measure), computed the same way for both.
Only box-and-plane scenes are translated.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sandbox import Scene, World
from sandbox.scene.library import resolve_scene
from sandbox.peers import pybullet_ke, pybullet_version, pybullet_world


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=300)
    ap.add_argument("--steps", type=int, default=20, help="timed steps per engine and round")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--solvers", default="pgs,mass-splitting,block-mass-splitting")
    a = ap.parse_args()
    import taichi as ti

    scene = Scene.load(resolve_scene(a.scene))
    pb, cid, ids, masses, inertias = pybullet_world(scene, a.iterations)
    solvers = a.solvers.split(",")
    worlds = {s: World(scene, solver=s, iterations=a.iterations, arch="cpu") for s in solvers}

    def step_pybullet(n):
        for _ in range(n):
            pb.stepSimulation(physicsClientId=cid)

    def stepper(world):
        def run(n):
            world.step(n)
            ti.sync()
        return run

    pb_name = "pybullet " + pybullet_version()
    engines = {pb_name: step_pybullet, **{s: stepper(w) for s, w in worlds.items()}}
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
        step_pybullet(1)
        ke[pb_name].append(pybullet_ke(pb, cid, ids, masses, inertias))
        for s, w in worlds.items():
            w.step(1)
            ke[s].append(w.metrics()["kinetic_energy"])
    print(f"{a.scene}, {a.iterations} iterations, settle {a.settle}, {a.rounds} rounds of {a.steps} timed steps "
          "per engine, interleaved")
    pb_rates = np.asarray(rates[pb_name])
    for name in engines:
        r = np.asarray(rates[name])
        line = f"{name:24s} {np.median(r):8.1f} steps/s   KE(60 steps) {np.mean(ke[name]):.3e} J"
        if name != pb_name:
            ratio = r / pb_rates
            line += (f"   ratio to pybullet: median {np.median(ratio):.2f}x "
                     f"(rounds {ratio.min():.2f}-{ratio.max():.2f}x)")
        print(line, flush=True)


if __name__ == "__main__":
    main()
