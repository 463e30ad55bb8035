"""Our solvers and pybullet on the same scene, same dt and iteration count, in one run.

    pip install -e ".[peers]"
    python benchmarks/peer_pybullet.py [--scene pile_1000] [--iterations 15] [--settle 120] [--steps 60]
                                       [--solvers pgs,mass-splitting,block-mass-splitting]

pybullet is set up as the anchors in the team's RESULTS.md were: boxes as maximal-coordinate
rigid bodies with the scene's masses and half extents, a static plane, friction sqrt(0.5) per
body (Bullet multiplies the two coefficients, so every pair gets 0.5), no damping, no sleeping,
``numSolverIterations`` = iterations. Both engines settle ``--settle`` steps, then ``--steps``
steps are timed (our step includes collision, as ``stepSimulation`` does). Only box-and-plane
scenes are translated. Prints steps/s of each, the ratio, and the mean kinetic energy of the
last 60 steps (the jitter measure), computed the same way for both.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sandbox import Scene, World
from sandbox.scene.library import resolve_scene
from sandbox.bench import pybullet_version
from sandbox.peers import pybullet_ke, pybullet_world


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=120)
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--solvers", default="pgs,mass-splitting,block-mass-splitting")
    a = ap.parse_args()
    scene = Scene.load(resolve_scene(a.scene))
    pb, cid, ids, masses, inertias = pybullet_world(scene, a.iterations)
    for _ in range(a.settle):
        pb.stepSimulation(physicsClientId=cid)
    t = time.perf_counter()
    for _ in range(a.steps):
        pb.stepSimulation(physicsClientId=cid)
    pb_rate = a.steps / (time.perf_counter() - t)
    ke = []
    for _ in range(60):
        pb.stepSimulation(physicsClientId=cid)
        ke.append(pybullet_ke(pb, cid, ids, masses, inertias))
    print(f"{a.scene}, {a.iterations} iterations, settle {a.settle}, timed {a.steps} steps")
    print(f"{'pybullet ' + pybullet_version():24s} {pb_rate:8.1f} steps/s   KE(last 60) {np.mean(ke):.3e} J")
    import taichi as ti

    for solver in a.solvers.split(","):
        world = World(scene, solver=solver, iterations=a.iterations, arch="cpu")
        world.step(a.settle)
        ti.sync()
        t = time.perf_counter()
        world.step(a.steps)
        ti.sync()
        rate = a.steps / (time.perf_counter() - t)
        ke = []
        for _ in range(60):
            world.step(1)
            ke.append(world.metrics()["kinetic_energy"])
        print(f"{solver:24s} {rate:8.1f} steps/s   KE(last 60) {np.mean(ke):.3e} J   "
              f"ratio to pybullet {rate / pb_rate:.2f}x", flush=True)


if __name__ == "__main__":
    main()
