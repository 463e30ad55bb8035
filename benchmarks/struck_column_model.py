"""A 1-D model of the struck 1:1000 column under the split schedule's soft step: why the light
rows need more damping (docs/method-notes.md, "A struck column at 8 iterations").

Boxes of 1, 10, 100 and 1000 kg stand on the ground, one normal row per contact (the engine's four
points of a face lumped into one). Each substep: gravity, the warm start, S_b + ``--extra`` biased
Jacobi sweeps dividing by the split response K~ = sum n_b / m_b, the position update, S_b rigid
relax sweeps (S_b and the settings the shipped ones: formulation.sweep_plan, Settings). A row's spring is
the engine's (contact_spring.row_omega): 30 Hz or stiffer to hold the load above it within the
deflection, capped at kappa sqrt(S K / K~) / h with S = 2 S_b + extra (contact_spring.light_sweeps);
it is preloaded with that load beyond what its spring holds at the deflection, and below its preload
it is rigid, as in rows.solve_point (``--offset``: soft there too). After ``--settle`` steps the top
box is struck down. A model, not the engine: it matches the engine's verdicts, not its figures.

    python benchmarks/struck_column_model.py                 # zeta x iterations table
    python benchmarks/struck_column_model.py --offset        # rows soft below their preload

Prints, per damping ratio and iteration count, the mean kinetic energy of the last second and the
deepest penetration after the kick, and the spectral radius of the substep map of the soft regime
(every row above its preload: a linear map, stable when below 1).
"""

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from sandbox import Settings  # noqa: E402
from sandbox.formulation import SOFT_STEP, sweep_plan  # noqa: E402
from sandbox.solvers.contact_spring import light_sweeps  # noqa: E402

SETTINGS = Settings()
MASSES = np.array([1.0, 10.0, 100.0, 1000.0])
G = 9.81
DT = 1.0 / 60.0
DEFLECTION = SETTINGS.contact_deflection * 0.866  # x a unit box's bounding radius [m]


def sweeps(iterations, extra):
    """(biased and relax sweeps of a substep besides the extra ones, S of the light rows' limit)."""
    plan = sweep_plan(SOFT_STEP, iterations, SETTINGS.sweeps, extra, SETTINGS.step_sweeps)
    return plan.biased, light_sweeps(plan.biased, plan.ratio, True)


def _column(zeta, iterations, extra, kappa):
    """(J, inverse masses, K~, bias rate, gamma, preload, h, sweeps of each kind) of the column's rows."""
    n = len(MASSES)
    jac = np.eye(n) - np.eye(n, k=-1)  # row i: box i's velocity minus the one below it
    inv = 1.0 / MASSES
    n_b = np.array([2.0] * (n - 1) + [1.0])  # rows per box
    k_true = np.abs(jac) @ inv
    k_split = np.abs(jac) @ (n_b * inv)
    h = DT / iterations
    weight_above = G * np.cumsum(MASSES[::-1])[::-1]
    wanted = np.maximum(2.0 * np.pi * min(SETTINGS.contact_hertz, 0.25 / h),
                        np.sqrt(weight_above * k_true / DEFLECTION))
    each, limit_sweeps = sweeps(iterations, extra)
    cap = kappa * np.sqrt(limit_sweeps * k_true / k_split) / h
    omega = np.minimum(wanted, cap)
    rate = omega / (2.0 * zeta + h * omega)
    gamma = k_true / (h * omega * (2.0 * zeta + h * omega))
    preload = np.maximum(weight_above - omega ** 2 * DEFLECTION / k_true, 0.0) * h
    return jac, inv, k_split, rate, gamma, preload, h, each


def struck(zeta, iterations, extra=SETTINGS.ratio_sweeps, kappa=SETTINGS.contact_stiffness_limit, kick=300.0,
           settle=600, steps=600, offset=False):
    """(mean KE of the last second [J], deepest penetration after the kick [m])."""
    jac, inv, k_split, rate, gamma, preload, h, each = _column(zeta, iterations, extra, kappa)
    rest = np.arange(len(MASSES)) + 0.5  # unit boxes just touching: separations are J (x - rest)
    x = rest.copy()
    v = np.zeros_like(x)
    lam = np.zeros_like(x)

    def push(dl):
        return inv * (jac.T @ dl)

    kinetic, depth = [], 0.0
    for step in range(settle + steps):
        if step == settle:
            v[-1] -= kick / MASSES[-1]
        for _ in range(iterations):
            v = v - G * h + push(lam)
            s = jac @ (x - rest)
            target = np.where(s > 0.0, s / h, np.maximum(rate * np.minimum(s + SETTINGS.slop, 0.0),
                                                          -SETTINGS.max_push_speed))
            for _ in range(each + extra):
                w = jac @ v
                rigid = lam - (w + target) / k_split
                soft = lam - (w + target + gamma * (lam - preload)) / (k_split + gamma)
                use_soft = (rigid > preload) | (offset & (preload > 0.0) & (s <= 0.0))
                new = np.maximum(np.where(use_soft, soft, rigid), 0.0)
                v = v + push(new - lam)
                lam = new
            x = x + v * h
            s = jac @ (x - rest)
            for _ in range(each):
                new = np.maximum(lam - (jac @ v + np.maximum(s, 0.0) / h) / k_split, 0.0)
                v = v + push(new - lam)
                lam = new
        if step >= settle:
            kinetic.append(0.5 * float(MASSES @ (v * v)))
            depth = max(depth, float(-(jac @ (x - rest)).min()))
    return float(np.mean(kinetic[-60:])), depth


def soft_regime_radius(zeta, iterations, extra=SETTINGS.ratio_sweeps, kappa=SETTINGS.contact_stiffness_limit):
    """Spectral radius of one substep's map (x, v, lambda) -> (x, v, lambda) with every row soft."""
    jac, inv, k_split, rate, gamma, _, h, each = _column(zeta, iterations, extra, kappa)
    n = len(MASSES)

    def substep(z):
        x, v, lam = z[:n], z[n:2 * n], z[2 * n:]
        v = v + inv * (jac.T @ lam)
        s = jac @ x
        for _ in range(each + extra):
            new = lam - (jac @ v + rate * s + gamma * lam) / (k_split + gamma)
            v, lam = v + inv * (jac.T @ (new - lam)), new
        x = x + v * h
        for _ in range(each):
            new = lam - (jac @ v) / k_split
            v, lam = v + inv * (jac.T @ (new - lam)), new
        return np.concatenate([x, v, lam])

    matrix = np.column_stack([substep(e) for e in np.eye(3 * n)])
    return float(np.abs(np.linalg.eigvals(matrix)).max())


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--zetas", default="10,20,22,25,30,40")
    parser.add_argument("--iterations", default="4,8,15")
    parser.add_argument("--extra", type=int, default=SETTINGS.ratio_sweeps,
                        help="extra biased sweeps (Settings.ratio_sweeps)")
    parser.add_argument("--offset", action="store_true", help="preloaded rows stay soft below their preload")
    args = parser.parse_args()
    print(f"{'zeta':>5} {'its':>4} {'KE last s [J]':>14} {'max pen [mm]':>13} {'soft-regime radius':>19}")
    for zeta in (float(z) for z in args.zetas.split(",")):
        for its in (int(k) for k in args.iterations.split(",")):
            ke, pen = struck(zeta, its, args.extra, offset=args.offset)
            radius = soft_regime_radius(zeta, its, args.extra)
            print(f"{zeta:5g} {its:4d} {ke:14.3g} {pen * 1e3:13.1f} {radius:19.6f}")


if __name__ == "__main__":
    main()
