"""How stiff the contacts of a tall column are under each schedule, and whether the column holds.

    python benchmarks/column_buckling.py [--boxes 20] [--solvers pgs,block-mass-splitting,mass-splitting,jacobi]
                                         [--iterations 8,12,15] [--limits 0.6] [--sweeps 1] [--rocking 1.0]
                                         [--steps 600]

The hard case ``nudged_stack_20`` (sandbox/hard_cases.py: the column's top box nudged at 1 mm/s at
0.5 s) run once per schedule, iteration count, stiffness limit (``contact_stiffness_limit``, kappa),
biased sweep count and rocking stiffness (``contact_rocking_stiffness``; 0: off). A column of boxes
on springs buckles under its own weight (P-Delta) when the springs are too soft in rotation, however
stable the solve; a spring that is too stiff for the schedule rings instead (docs/method-notes.md,
"Why low iteration counts blew up"). Per run it prints the median contact spring between two boxes,
omega [rad/s] (from the rows' bias rate, ``rate = omega / (2 zeta + h omega)``; what the column's
compression meets, its rocking meets up to 1 + ``contact_rocking_stiffness`` times that stiffness)
and omega h, the lean's growth rate over the second half of the run (a log-linear fit of the top
box's sideways offset: above 0 it grows, i.e. the column is buckling), the top box's largest offset
and the mean kinetic energy of the last second (a ringing spring shows there). docs/method-notes.md,
"The nudged column at 8 iterations", has the figures and what they mean.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sandbox import Scene, World  # noqa: E402
from sandbox.hard_cases import nudged_stack  # noqa: E402
from sandbox.settings import Settings  # noqa: E402
from sandbox.solvers.schedule import Schedule  # noqa: E402


def spring_omega(world: World, h: float, zeta: float) -> float:
    """Median omega [rad/s] of the normal rows between two dynamic bodies (the column's joints)."""
    c, rows = world.buf.contacts, world.buf.rows
    n = int(c.count[None])
    a, b = c.body_a.to_numpy()[:n], c.body_b.to_numpy()[:n]
    dynamic = world.buf.bodies.inv_mass.to_numpy() > 0.0
    inner = dynamic[a] & dynamic[b]
    rate = rows.rate.to_numpy()[:n][inner].astype(np.float64)
    omega = 2.0 * zeta * rate / (1.0 - h * rate)  # rate = omega / (2 zeta + h omega)
    return float(np.median(omega)) if omega.size else float("nan")


def lean_growth(times: np.ndarray, offsets: np.ndarray) -> float:
    """[1/s] Slope of log |offset| over the second half of the run (nan when it stays below 1 um)."""
    half = len(times) // 2
    t, x = times[half:], np.abs(offsets[half:])
    keep = x > 1e-6
    if keep.sum() < 10:
        return float("nan")
    return float(np.polyfit(t[keep], np.log(x[keep]), 1)[0])


def run(boxes: int, solver: str, iterations: int, limit: float, sweeps: int, rocking: float, steps: int) -> dict:
    case = nudged_stack(boxes)
    scene = Scene.from_dict(case.scene, source=case.name)
    settings = Settings().replace(**scene.world.settings_given()).replace(contact_stiffness_limit=limit,
                                                                            sweeps=sweeps,
                                                                            contact_rocking_stiffness=rocking)
    world = World(scene, solver=solver, iterations=iterations, settings=settings)
    try:
        dt = world.dt
        h = dt / iterations
        start = world.state()["position"][-1, 0]
        offsets, ke = [], []
        omega = float("nan")
        for k in range(steps):
            world.step(1)
            offsets.append(world.state()["position"][-1, 0] - start)
            ke.append(world.metrics()["kinetic_energy"])
            if k == steps // 2:
                omega = spring_omega(world, h, settings.contact_damping_ratio)
        offsets = np.array(offsets)
        last_second = max(1, int(round(1.0 / dt)))
        biased = Schedule(solver, {}).plan(settings, iterations).biased  # more below 8 (step_sweeps)
        return {"omega": omega, "omega_h": omega * h, "biased": biased,
                "growth": lean_growth(dt * np.arange(1, steps + 1), offsets),
                "drift_mm": 1e3 * float(np.abs(offsets).max()), "ke": float(np.mean(ke[-last_second:]))}
    finally:
        world.close()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--boxes", type=int, default=20)
    p.add_argument("--solvers", default="pgs,block-mass-splitting,mass-splitting,jacobi")
    p.add_argument("--iterations", default="8,12,15")
    p.add_argument("--limits", default="0.6", help="contact_stiffness_limit values (kappa), comma-separated")
    p.add_argument("--sweeps", default="1", help="Settings.sweeps values, comma-separated (the table shows the "
                   "biased sweeps per substep the plan ran: the Jacobi family sweeps more below 8 iterations)")
    p.add_argument("--rocking", default="1.0", help="contact_rocking_stiffness values, comma-separated (0: off)")
    p.add_argument("--steps", type=int, default=600)
    args = p.parse_args(argv)
    print(f"nudged_stack_{args.boxes}, {args.steps} steps; lean growth > 0: the column is buckling")
    print("| solver | iterations | kappa | biased sweeps | rocking | omega [rad/s] | omega h | lean growth [1/s] "
          "| top offset, largest [mm] | mean KE, last second [J] |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
    for solver in args.solvers.split(","):
        for iterations in (int(v) for v in args.iterations.split(",")):
            for limit in (float(v) for v in args.limits.split(",")):
                for sweeps in (int(v) for v in args.sweeps.split(",")):
                    for rocking in (float(v) for v in args.rocking.split(",")):
                        r = run(args.boxes, solver, iterations, limit, sweeps, rocking, args.steps)
                        print(f"| {solver} | {iterations} | {limit:g} | {r['biased']} | {rocking:g} | {r['omega']:.0f} "
                              f"| {r['omega_h']:.3f} | {r['growth']:+.2f} | {r['drift_mm']:.2f} | {r['ke']:.2e} |",
                              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
