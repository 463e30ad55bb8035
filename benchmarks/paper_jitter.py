"""The seeds' figure under both time-stepping schemes: a resting pyramid's kinetic energy per
frame, serial PGS, shuffled parallel PGS and mass splitting, at 15 and 500 iterations.

    PYTHONPATH=$PWD python benchmarks/paper_jitter.py [--frames 600] [--out docs/paper_jitter.png]

``formulation = "paper"`` is the scheme of Tonge et al. and the slides (one velocity solve per
step, Baumgarte gamma 0.8, warm start); ``"soft-step"`` is this sandbox's default (Box2D v3's
substeps). The 210-box pyramid of 1000 kg boxes starts touching, at rest; no sleeping, no
damping. Prints, per run, the mean kinetic energy over the last 60 frames, the top box's
displacement, the largest speed reached and the time per step, and draws every curve.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from sandbox import Scene, Settings, World
from sandbox.scene.library import resolve_scene

SOLVERS = [
    ("pgs", {}, "serial PGS"),
    ("pgs-colored", {"shuffle": True}, "parallel PGS, shuffled"),
    ("mass-splitting", {}, "mass splitting"),
]
RUNS = [(f, k) for f in ("paper", "soft-step") for k in (15, 500)]
EXTRA = [("paper", 15, "mass-splitting", {}, {"warm_start": 0.5}, "mass splitting, warm start 0.5")]


def run(formulation: str, iterations: int, solver: str, options: dict, settings: dict, frames: int) -> dict:
    scene = Scene.load(resolve_scene("pyramid_20"))
    s = Settings().replace(**scene.world.settings_given(), formulation=formulation, **settings)
    world = World(scene, solver=solver, iterations=iterations, arch="cpu", settings=s, **options)
    start = world.state()["position"].copy()
    top = int(np.argmax(start[:, 2]))
    ke, peak = np.empty(frames), 0.0
    world.step(1)  # compile outside the timing
    t0 = time.perf_counter()
    for f in range(frames):
        if f:
            world.step(1)
        ke[f] = world.metrics()["kinetic_energy"]
        peak = max(peak, float(np.linalg.norm(world.state(["linear_velocity"])["linear_velocity"], axis=1).max()))
    ms = 1e3 * (time.perf_counter() - t0) / max(frames - 1, 1)
    moved = float(np.linalg.norm(world.state()["position"][top] - start[top]))
    return {"ke": ke, "mean_ke": float(ke[-60:].mean()), "top_moved": moved, "peak_speed": peak, "ms": ms}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--out", default="docs/paper_jitter.png")
    a = ap.parse_args()
    cases = [(f, k, s, o, {}, label) for f, k in RUNS for s, o, label in SOLVERS] + EXTRA
    results = {}
    print("| formulation | iterations | solver | mean KE, last 60 frames [J] | top box moved [mm] | peak speed [m/s] "
          "| ms/step |")
    print("|---|--:|---|--:|--:|--:|--:|")
    for formulation, k, solver, options, settings, label in cases:
        r = run(formulation, k, solver, options, settings, a.frames)
        results[(formulation, k, label)] = r
        print(f"| {formulation} | {k} | {label} | {r['mean_ke']:.2e} | {1e3 * r['top_moved']:.1f} | "
              f"{r['peak_speed']:.2f} | {r['ms']:.1f} |", flush=True)
    for formulation, k in RUNS:
        ms = results[(formulation, k, "mass splitting")]["mean_ke"]
        pgs = results[(formulation, k, "parallel PGS, shuffled")]["mean_ke"]
        print(f"{formulation}, {k} iterations: shuffled parallel PGS / mass splitting = {pgs / ms:.3g}x")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True, sharey=True)
    frames = np.arange(1, a.frames + 1)
    for ax, (formulation, k) in zip(axes.flat, RUNS):
        for (f, kk, label), r in results.items():
            if (f, kk) == (formulation, k):
                ax.semilogy(frames, np.maximum(r["ke"], 1e-12), lw=1, label=label)
        ax.set_title(f"{formulation}, {k} iterations")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("frame (dt = 1/60 s)")
    for ax in axes[:, 0]:
        ax.set_ylabel("kinetic energy [J]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("210-box pyramid (1000 kg boxes) from rest: the paper's scheme against the soft step")
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    with open(a.out.rsplit(".", 1)[0] + ".json", "w") as fh:
        json.dump({" | ".join(map(str, key)): {k: ([float(f"{x:.4g}") for x in v] if isinstance(v, np.ndarray) else v)
                                               for k, v in r.items()} for key, r in results.items()}, fh)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
