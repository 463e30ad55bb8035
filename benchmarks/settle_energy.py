"""How a scene settles: the mean kinetic energy of the 60 steps before each mark, ours beside the peers.

    pip install -e ".[peers]"
    python benchmarks/settle_energy.py [--scene pile_1000] [--iterations 15] [--marks 300,600,900,1200,1800,2400]
                                       [--solvers mass-splitting] [--peers rapier-t1]

peer_speed.py prints one such figure, 60 steps after its timed rounds; on a pile still settling
that figure depends on where the history happens to be (ours 33 J and Rapier's 1.6 J at step 600 of
pile_1000, 0.78 J and 3.3 J at step 900, before the manifold's reduction changed). The marks show
whether the energy falls to a floor and where the floor is. For each of our solvers the line also
names the body with the most kinetic energy at the mark and its share: one body rocking for good
carried ~all of the settled pile's 0.6 J (docs/method-notes.md "A rocking box"). The peers are
``sandbox/peers.py``'s (same dt, iterations, friction 0.5, no damping, no sleeping); the engines
step in lockstep, so the run takes as long as all of them together.
"""

from __future__ import annotations

import argparse
import platform

import numpy as np

from sandbox import Scene, World
from sandbox.peers import PEERS
from sandbox.scene.library import resolve_scene
from sandbox.scene.rotations import quat_to_matrix

WINDOW = 60
"""Steps averaged before each mark (peer_speed.py's kinetic-energy window)."""


def _body_energies(world: World) -> np.ndarray:
    """Each body's kinetic energy [J]: translation, and rotation with its body-frame inertia."""
    s = world.state()
    mass = np.array([b.mass for b in world.body_specs])
    inertia = np.array([b.inertia for b in world.body_specs])
    w_body = np.einsum("nji,nj->ni", quat_to_matrix(s["orientation"].astype(float)), s["angular_velocity"])
    rot = 0.5 * np.einsum("ni,nij,nj->n", w_body, inertia, w_body)
    return 0.5 * mass * np.sum(s["linear_velocity"] ** 2, axis=1) + rot


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--marks", default="300,600,900,1200,1800,2400")
    ap.add_argument("--solvers", default="mass-splitting")
    ap.add_argument("--peers", default="rapier-t1", help="comma-separated, or 'none'")
    a = ap.parse_args()
    marks = sorted(int(m) for m in a.marks.split(","))
    scene = Scene.load(resolve_scene(a.scene))
    ours = {s: World(scene, solver=s, iterations=a.iterations, arch="cpu") for s in a.solvers.split(",")}
    peers = {}
    for name in ([] if a.peers == "none" else a.peers.split(",")):
        ok, why = PEERS[name].available()
        if not ok:
            raise SystemExit(f"{name}: {why}")
        peers[f"{name} {PEERS[name].version()}"] = PEERS[name].open(scene, a.iterations)
    print(f"# {platform.processor() or platform.machine()}, {a.scene}, {a.iterations} iterations; mean kinetic "
          f"energy [J] of the {WINDOW} steps before each mark")
    sums = {name: 0.0 for name in [*ours, *peers]}
    step = 0
    for mark in marks:
        for name in sums:
            sums[name] = 0.0
        while step < mark:
            for world in ours.values():
                world.step(1)
            for peer in peers.values():
                peer.step()
            step += 1
            if mark - step < WINDOW:
                for name, world in ours.items():
                    sums[name] += world.metrics()["kinetic_energy"]
                for name, peer in peers.items():
                    sums[name] += peer.kinetic_energy()
        cells = []
        for name, world in ours.items():
            e = _body_energies(world)
            top = int(np.argmax(e))
            share = e[top] / e.sum() if e.sum() > 0.0 else 0.0
            cells.append(f"{name} {sums[name] / WINDOW:.2e} (body {top}: {share:.0%})")
        cells += [f"{name} {sums[name] / WINDOW:.2e}" for name in peers]
        print(f"step {mark:5d}: " + "   ".join(cells), flush=True)
    for world in ours.values():
        world.close()


if __name__ == "__main__":
    main()
