"""What the impact rows' clamped warm start costs: the same scene stepped by two worlds in one
process, interleaved in blocks of 10 steps, one as shipped and one whose
``restitution_threshold`` is so high that no row is an impact (impact_carry.is_impact), so no step
lists a carry to clamp after its folded warm starts (mass_splitting.clamp_folded_carries).

    python benchmarks/impact_carry.py [--scene pile_1000] [--solver mass-splitting]
                                      [--iterations 15] [--windows 1,60,150,300,450]

Prints, per window of steps, ms/step of each world, their ratio, and how many of the shipped
world's steps had an impact row. The two worlds' piles part ways as they land (their physics
differs), so a window compares similar, not identical, contact sets; a scene without restitution
is otherwise the same in both (the threshold only decides restitution and impacts).
"""

from __future__ import annotations

import argparse
import time

from sandbox import Scene, World
from sandbox.scene.library import resolve_scene

BLOCK = 10
NO_IMPACTS = 1e9
"""[m/s] A restitution threshold no approach reaches."""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="pile_1000")
    ap.add_argument("--solver", default="mass-splitting")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--windows", default="1,60,150,300,450", help="step boundaries of the timed windows")
    a = ap.parse_args()
    bounds = [int(x) for x in a.windows.split(",")]
    scene = Scene.load(resolve_scene(a.scene))
    clamped = World(scene, solver=a.solver, iterations=a.iterations, arch="cpu")
    folded = World(scene, solver=a.solver, iterations=a.iterations, arch="cpu",
                   settings=clamped.settings.replace(restitution_threshold=NO_IMPACTS))
    for w in (clamped, folded):  # compile outside the timings
        w.step(bounds[0])
    print(f"# {a.scene}, {a.solver}, {a.iterations} iterations; blocks of {BLOCK} steps, interleaved")
    for lo, hi in zip(bounds, bounds[1:]):
        t_clamped = t_folded = 0.0
        impact_steps = 0
        k = lo
        while k < hi:
            n = min(BLOCK, hi - k)
            for _ in range(n):
                t = time.perf_counter()
                clamped.step(1)
                t_clamped += time.perf_counter() - t
                impact_steps += int(clamped.buf.rows.impacts[None])
            t = time.perf_counter()
            folded.step(n)
            t_folded += time.perf_counter() - t
            k += n
        steps = hi - lo
        print(f"steps {lo:4d}-{hi:4d}: clamped {1e3 * t_clamped / steps:6.2f} ms/step, folded "
              f"{1e3 * t_folded / steps:6.2f} ms/step, ratio {t_clamped / t_folded:.3f}, "
              f"{impact_steps}/{steps} steps with an impact row")


if __name__ == "__main__":
    main()
