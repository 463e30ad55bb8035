"""The seeds' figure under both time-stepping schemes: a resting pyramid's kinetic energy per
frame, serial PGS, shuffled parallel PGS and mass splitting, at 15 and 500 iterations.
``--scene`` runs another shipped scene instead (sleeping switched off: it must not hide jitter);
``--settle N`` first brings the scene to rest with N steps of serial PGS at 100 iterations under
the same scheme and then switches to the solver measured (the warm-start impulses are kept), so
the run starts from a converged resting state rather than from release; ``--block`` adds block
mass splitting.

    PYTHONPATH=$PWD python benchmarks/paper_jitter.py [--frames 600] [--out docs/paper_jitter.png]
        [--scene pyramid_20] [--iterations 15,500] [--settle 0] [--block]

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
FORMULATIONS = ("paper", "soft-step")
SETTLE_ITERATIONS = 100  # serial PGS, for --settle
MOVING = 1e-3  # [m] a body that moved this far over the last 60 frames counts as moving
BLOCK = ("block-mass-splitting", {}, "block mass splitting")
EXTRA = [("paper", 15, "mass-splitting", {}, {"warm_start": 0.5}, "mass splitting, warm start 0.5")]


def run(scene_name: str, formulation: str, iterations: int, solver: str, options: dict, settings: dict, frames: int,
        settle: int = 0) -> dict:
    scene = Scene.load(resolve_scene(scene_name))
    s = Settings().replace(**scene.world.settings_given(), formulation=formulation, **settings)
    if settle:
        world = World(scene, solver="pgs", iterations=SETTLE_ITERATIONS, arch="cpu", settings=s)
    else:
        world = World(scene, solver=solver, iterations=iterations, arch="cpu", settings=s, **options)
    world.set_effects(tuple(e for e in world.effects if e != "sleeping"))  # sleeping would hide jitter
    if settle:
        world.step(settle)
        world.set_solver(solver, iterations=iterations, **options)
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
        if f == frames - 61:
            before_last_second = world.state()["position"].copy()
    ms = 1e3 * (time.perf_counter() - t0) / max(frames - 1, 1)
    end = world.state()["position"]
    moved = float(np.linalg.norm(end[top] - start[top]))
    last_second = np.linalg.norm(end - before_last_second, axis=1)
    return {"ke": ke, "mean_ke": float(ke[-60:].mean()), "top_moved": moved, "peak_speed": peak, "ms": ms,
            "moving": int((last_second > MOVING).sum())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--out", default="docs/paper_jitter.png")
    ap.add_argument("--scene", default="pyramid_20")
    ap.add_argument("--iterations", default="15,500", help="comma-separated iteration counts")
    ap.add_argument("--settle", type=int, default=0, help="steps of serial PGS at 100 iterations first")
    ap.add_argument("--block", action="store_true", help="add block mass splitting")
    a = ap.parse_args()
    runs = [(f, int(k)) for f in FORMULATIONS for k in a.iterations.split(",")]
    solvers = SOLVERS + ([BLOCK] if a.block else [])
    cases = [(f, k, s, o, {}, label) for f, k in runs for s, o, label in solvers]
    cases += [c for c in EXTRA if (c[0], c[1]) in runs and a.scene == "pyramid_20" and not a.settle]
    results = {}
    print(f"{a.scene}, {a.frames} frames" + (f" after {a.settle} settling steps (serial PGS, "
                                              f"{SETTLE_ITERATIONS} iterations)" if a.settle else " from rest"))
    print("| formulation | iterations | solver | mean KE, last 60 frames [J] | top box moved [mm] | peak speed [m/s] "
          "| bodies moving | ms/step |")
    print("|---|--:|---|--:|--:|--:|--:|--:|")
    for formulation, k, solver, options, settings, label in cases:
        r = run(a.scene, formulation, k, solver, options, settings, a.frames, a.settle)
        results[(formulation, k, label)] = r
        print(f"| {formulation} | {k} | {label} | {r['mean_ke']:.2e} | {1e3 * r['top_moved']:.1f} | "
              f"{r['peak_speed']:.2f} | {r['moving']} | {r['ms']:.1f} |", flush=True)
    for formulation, k in runs:
        ms = results[(formulation, k, "mass splitting")]["mean_ke"]
        pgs = results[(formulation, k, "parallel PGS, shuffled")]["mean_ke"]
        print(f"{formulation}, {k} iterations: shuffled parallel PGS / mass splitting = {pgs / ms:.3g}x")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = len(runs) // len(FORMULATIONS)
    fig, axes = plt.subplots(len(FORMULATIONS), cols, figsize=(5.5 * cols, 7), sharex=True, sharey=True, squeeze=False)
    frames = np.arange(1, a.frames + 1)
    for ax, (formulation, k) in zip(axes.flat, runs):
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
    fig.suptitle(f"{a.scene}" + (f" settled by serial PGS ({a.settle} steps)" if a.settle else " from rest")
                 + ": the paper's scheme against the soft step")
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    with open(a.out.rsplit(".", 1)[0] + ".json", "w") as fh:
        json.dump({" | ".join(map(str, key)): {k: ([float(f"{x:.4g}") for x in v] if isinstance(v, np.ndarray) else v)
                                               for k, v in r.items()} for key, r in results.items()}, fh)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
