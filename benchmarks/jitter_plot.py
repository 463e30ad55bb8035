"""The jitter claim, measured: kinetic energy of the 210-box pyramid vs frame, per solver.

    python benchmarks/jitter_plot.py [--iterations 15] [--frames 600] [--out docs/jitter_pyramid.png]

Sleeping does not exist in this engine and no damping is added: what remains in
a resting pyramid is the solver's own residual motion. Parallel PGS is run with
``shuffle`` (a new contact and colour order every frame, as parallel hardware
produces), which is what makes it jitter; mass splitting is order independent.
Prints the mean kinetic energy over the last 60 frames and the ratio.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from sandbox import Scene, World
from sandbox.scene.library import resolve_scene

RUNS = [
    ("pgs", {}, "PGS (serial, fixed order)"),
    ("pgs-colored", {"shuffle": True}, "parallel PGS, shuffled order"),
    ("jacobi", {}, "projected Jacobi"),
    ("mass-splitting", {}, "mass splitting"),
    ("block-mass-splitting", {}, "block mass splitting"),
]


def kinetic_energy_series(solver: str, options: dict, iterations: int, frames: int) -> np.ndarray:
    world = World(Scene.load(resolve_scene("pyramid_20")), solver=solver, iterations=iterations, arch="cpu", **options)
    ke = np.empty(frames)
    for f in range(frames):
        world.step(1)
        ke[f] = world.metrics()["kinetic_energy"]
    return ke


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--out", default="docs/jitter_pyramid.png")
    a = ap.parse_args()
    series = {}
    for solver, opts, label in RUNS:
        series[label] = kinetic_energy_series(solver, opts, a.iterations, a.frames)
        print(f"{label:32s} mean KE over last 60 frames: {series[label][-60:].mean():.3e} J", flush=True)
    ms = series["mass splitting"][-60:].mean()
    pgs = series["parallel PGS, shuffled order"][-60:].mean()
    print(f"ratio shuffled parallel PGS / mass splitting: {pgs / ms:.1f}x")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for label, ke in series.items():
        ax.semilogy(np.arange(1, a.frames + 1), np.maximum(ke, 1e-12), label=label, lw=1)
    ax.set_xlabel("frame (dt = 1/60 s)")
    ax.set_ylabel("kinetic energy [J]")
    ax.set_title(f"210-box pyramid at rest, {a.iterations} iterations, no sleeping, no damping")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    with open(a.out.rsplit(".", 1)[0] + ".json", "w") as fh:
        json.dump({k: v.tolist() for k, v in series.items()}, fh)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
