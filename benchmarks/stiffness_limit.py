"""How stiff a contact spring each schedule can carry, and why (docs/method-notes.md,
"Why low iteration counts blew up").

    python benchmarks/stiffness_limit.py model                    # seconds: numpy only
    python benchmarks/stiffness_limit.py buckling [--boxes 20]    # seconds: numpy only
    python benchmarks/stiffness_limit.py split-weights [--masses 1,10,100,1000]  # seconds: numpy
    python benchmarks/stiffness_limit.py scan [pyramid_20] [--steps 300]
            [--solvers pgs,mass-splitting,block-mass-splitting] [--iterations 1,2,4,8,15,30]
            [--hertz 5,10,15,20,30,45,60]                         # ~30 min on 2 cores

``model``: the soft step of solvers/rows.py on a column of N unit boxes (1000 kg, one
contact point per face, vertical motion only, every contact active), as a linear map
of one step (positions, velocities, accumulated impulses); prints its spectral radius
for serial PGS and per-point mass splitting at 30 Hz, without and with the per-row
stability limit (contact_spring.py). Above 1 a resting column gains energy every step.
The growing mode is the column's slowest (quarter-wave) one.

``buckling``: why a tall column falls at few iterations although no row gains energy. The
limit caps each row's spring, and a column of boxes on capped springs is an elastic column:
its faces turn under the weight above them (P-Delta) and the springs at a face's edges turn
them back. Rigid boxes with unit faces, four points per face, each point a spring of
``m_eff omega^2`` (m_eff = 1 / K, the row's effective mass): a face resists turning with
``f m_eff omega^2 (0.5 m)^2 x 4``, f = 1 for four springs about the face's middle and f ~ 2
when the preload (contact_spring.py) holds the unloading edge rigid and the face turns about
it. The smallest eigenvalue of stiffness minus the weight's geometric stiffness gives the
column's critical omega for both; each schedule's cap (its K~ / K for an interior box of the
column) against it predicts which iteration counts let the column stand.

``split-weights``: why the heavy-on-light column converges so slowly under mass splitting, and
why no other split of the bodies' masses helps. A vertical chain ground - m1 - m2 - ... (one
contact point per face, all active) solved by the split Jacobi sweep with body i's mass shared
among its contacts in fractions w (sum 1; the equal split is mass splitting's 1 / n_b): the
sweep is ``lambda <- lambda - B^-1 (A lambda + b)`` with A the Delassus matrix and B its
diagonal built from the sub-bodies' masses m_i w. Cauchy-Schwarz gives B >= A for any such
w (the convergence proof holds), and the spectral radius of ``I - B^-1 A`` is how much of the
slowest mode's error one sweep leaves. Prints it for the equal split, for shares following the
partner's mass (and its square root), and the best of a grid of shares.

``scan``: the engine itself, with the limit turned off (``contact_stiffness_limit = 0``):
for each schedule, iteration count and ``contact_hertz``, the mean kinetic energy of the
last 60 of ``--steps`` frames, the peak speed and the top body's displacement. The largest
stable frequency per row shows the limit omega h ~ kappa sqrt(S K / K~).
"""

from __future__ import annotations

import argparse
import math

import numpy as np


# ----------------------------------------------------------------------------- the model
def _spring(h, omega, zeta):
    """(bias rate, softness 1 / c) of a spring of ``omega`` over a substep ``h``."""
    c = h * omega * (2.0 * zeta + h * omega)
    return omega / (2.0 * zeta + h * omega), 1.0 / c


def column_step_radius(boxes: int, iterations: int, schedule: str, hertz: float = 30.0, zeta: float = 10.0,
                       dt: float = 1.0 / 60.0, points: int = 1, kappa: float | None = None) -> float:
    """Spectral radius of one step of the soft step on a column (module docstring).
    ``schedule``: "pgs" (points one by one, in place) or "ms" (every point from the same
    velocities, split masses). ``kappa``: the per-row stability limit, or None. With more
    than one point per face the rows of a face are exactly redundant in this 1-D model
    (no turning), which a real face is not."""
    n = boxes
    inv_m = np.full(n, 1.0 / 1000.0)
    h = dt / iterations
    k_a = np.concatenate([[0.0], inv_m[:-1]])  # contact j joins body j-1 (the ground for j = 0) and body j
    k_b = inv_m.copy()
    k = k_a + k_b
    split = np.full(n, 2.0 * points)
    split[-1] = points
    k_split = np.concatenate([[0.0], split[:-1]]) * k_a + split * k_b if schedule == "ms" else k
    omega = np.full(n, 2.0 * math.pi * min(hertz, 0.25 / h))
    if kappa is not None:
        omega = np.minimum(omega, kappa * np.sqrt(2.0 * k / k_split) / h)
    rate, softness = _spring(h, omega, zeta)
    gamma = softness * k

    def apply(v, impulse):
        v = v + impulse * inv_m
        v[:-1] -= impulse[1:] * inv_m[:-1]
        return v

    def sweep(v, lam, target, g):
        if schedule == "ms":
            w = v.copy()
            w[1:] -= v[:-1]
            dl = -(w[:, None] + target[:, None] + g[:, None] * lam) / (k_split + g)[:, None]
            return apply(v, dl.sum(1)), lam + dl
        v, lam = v.copy(), lam.copy()
        for j in range(n):
            for p in range(points):
                w = v[j] - (v[j - 1] if j else 0.0)
                dl = -(w + target[j] + g[j] * lam[j, p]) / (k[j] + g[j])
                lam[j, p] += dl
                v[j] += dl * inv_m[j]
                if j:
                    v[j - 1] -= dl * inv_m[j - 1]
        return v, lam

    def step(state):
        x, v, lam = state[:n].copy(), state[n:2 * n].copy(), state[2 * n:].reshape(n, points).copy()
        x0 = x.copy()
        sep0 = x - np.concatenate([[0.0], x[:-1]])
        sep = sep0
        for _ in range(iterations):
            v = apply(v, lam.sum(1))  # warm start (gravity is a constant: it drops out of the linear map)
            v, lam = sweep(v, lam, rate * sep, gamma)
            x = x + h * v
            moved = x - x0
            sep = sep0 + moved - np.concatenate([[0.0], moved[:-1]])
            v, lam = sweep(v, lam, 0.0 * sep, 0.0 * gamma)  # the rigid relax sweep
        return np.concatenate([x, v, lam.ravel()])

    size = n * (2 + points)
    base = step(np.zeros(size))
    jac = np.empty((size, size))
    for i in range(size):
        e = np.zeros(size)
        e[i] = 1e-3
        jac[:, i] = (step(e) - base) / 1e-3
    return float(np.abs(np.linalg.eigvals(jac)).max())


def run_model(args) -> None:
    from sandbox import Settings

    kappa = Settings().contact_stiffness_limit
    counts = [int(x) for x in args.iterations.split(",")]
    print(f"spectral radius of one step, {args.boxes}-box column, 30 Hz; > 1: a resting column gains energy")
    print(f"{'schedule':28s}" + "".join(f"{k:>9d} it" for k in counts))
    for schedule, label in (("pgs", "serial PGS"), ("ms", "mass splitting (per point)")):
        for limit in (None, kappa):
            row = [column_step_radius(args.boxes, k, schedule, kappa=limit) for k in counts]
            name = label + ("" if limit is None else f", limited {limit:g}")
            print(f"{name:28s}" + "".join(f"{r:12.4f}" for r in row), flush=True)


# ----------------------------------------------------------------------------- buckling
def column_is_stiff_enough(boxes: int, omega: float, turn_factor: float, mass: float = 1000.0,
                           gravity: float = 9.81) -> bool:
    """Whether a column of unit boxes whose every contact point is a spring of ``omega`` holds
    its weight without buckling (module docstring, ``buckling``)."""
    point_k = [mass / 4.0 * omega**2] + [mass / 8.0 * omega**2] * (boxes - 1)  # ground row K = 4/m, others 8/m
    face_k = [turn_factor * 4.0 * 0.25 * k for k in point_k]  # four points at +-0.5 m
    stiffness = np.zeros((boxes, boxes))
    for i, k in enumerate(face_k):  # face i turns box i against box i - 1 (the ground for i = 0)
        stiffness[i, i] += k
        if i:
            stiffness[i - 1, i - 1] += k
            stiffness[i, i - 1] -= k
            stiffness[i - 1, i] -= k
    # the weight above: box j's tilt lowers every box above it by (tilt^2 / 2) x 1 m, itself by half that
    geometric = np.diag([mass * gravity * (boxes - j - 0.5) for j in range(boxes)])
    return bool(np.linalg.eigvalsh(stiffness - geometric).min() > 0.0)


def critical_omega(boxes: int, turn_factor: float) -> float:
    lo, hi = 1.0, 1e4
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if column_is_stiff_enough(boxes, mid, turn_factor) else (mid, hi)
    return hi


def run_buckling(args) -> None:
    from sandbox import Settings

    settings = Settings()
    kappa, hertz = settings.contact_stiffness_limit, 60.0  # stack_20 and nudged_stack_20 ask for 60 Hz
    stiff, soft = critical_omega(args.boxes, 2.0), critical_omega(args.boxes, 1.0)
    print(f"{args.boxes}-box column of unit boxes: critical omega {stiff:.0f} rad/s with the preload's pivot "
          f"(f = 2), {soft:.0f} rad/s about the face's middle (f = 1); asked: {hertz:g} Hz = "
          f"{2 * math.pi * hertz:.0f} rad/s")
    from sandbox.solvers.schedule import Schedule

    ratios = {"serial PGS, colored PGS": ("pgs", 1.0),  # K~ / K of an interior box's row
              "projected Jacobi": ("jacobi", max(1.0 / settings.jacobi_relaxation, 8 / settings.split_relaxation)),
              "mass splitting": ("mass-splitting", max(1.0, 8 / settings.split_relaxation)),  # 4 points below + 4 above
              "block mass splitting": ("block-mass-splitting", 2.0)}  # one manifold below, one above
    counts = [int(x) for x in args.iterations.split(",")]
    print(f"each schedule's spring at the stability limit kappa = {kappa:g} [rad/s], then the prediction "
          "(buckles: below both; marginal: between; stands: above both)")
    print(f"{'schedule':26s}" + "".join(f"{k:>16d} it" for k in counts))
    for name, (solver, ratio) in ratios.items():
        cells = []
        for k in counts:
            h = 1.0 / 60.0 / k
            plan = Schedule(solver, {}).plan(settings, k)  # more sweeps below 8 (step_sweeps)
            omega = min(2 * math.pi * hertz, kappa * math.sqrt((plan.biased + plan.relax) / ratio) / h)
            verdict = "buckles" if omega < stiff else "marginal" if omega < soft else "stands"
            cells.append(f"{omega:7.0f} {verdict:>10s}")
        print(f"{name:26s}" + "".join(f"{c:>19s}" for c in cells))


# ----------------------------------------------------------------------------- split weights
def chain_sweep_radius(masses, shares) -> float:
    """Spectral radius of one linear split Jacobi sweep on the chain ground - masses[0] - masses[1]
    - ...; ``shares[i]`` = (share of body i's mass at its lower contact, at its upper one)."""
    m = np.asarray(masses, float)
    n = len(m)
    jac = np.eye(n) - np.eye(n, k=-1)  # contact k: body k's velocity up minus body k-1's
    delassus = jac @ np.diag(1.0 / m) @ jac.T
    diag = np.array([1.0 / (shares[k][0] * m[k]) + (1.0 / (shares[k - 1][1] * m[k - 1]) if k else 0.0)
                     for k in range(n)])
    return float(np.max(np.abs(np.linalg.eigvals(np.eye(n) - delassus / diag[:, None]))))


def partner_shares(masses, power: float) -> list:
    """Each body's shares in proportion to (the mass across each contact) ** power, the ground
    counted as heavy as the chain's heaviest body; the top body has one contact and keeps its whole
    mass there."""
    shares = []
    for k in range(len(masses) - 1):
        below = masses[k - 1] if k else max(masses)  # the ground
        lo, hi = below ** power, masses[k + 1] ** power
        shares.append((lo / (lo + hi), hi / (lo + hi)))
    return shares + [(1.0, 1.0)]


def best_grid_shares(masses, steps: int = 49) -> tuple:
    grid = np.linspace(0.02, 0.98, steps)
    best = (np.inf, None)
    for lows in np.array(np.meshgrid(*[grid] * (len(masses) - 1))).reshape(len(masses) - 1, -1).T:
        shares = [(w, 1.0 - w) for w in lows] + [(1.0, 1.0)]
        best = min(best, (chain_sweep_radius(masses, shares), tuple(lows)), key=lambda t: t[0])
    return best


def run_split_weights(args) -> None:
    masses = [float(x) for x in args.masses.split(",")]
    print(f"chain ground - {' - '.join(f'{m:g} kg' for m in masses)}: spectral radius of one split "
          "Jacobi sweep (1 - the slowest mode's convergence per sweep)")
    equal = partner_shares(masses, 0.0)
    print(f"  equal split (mass splitting)       {chain_sweep_radius(masses, equal):.8f}")
    for power in (0.5, 1.0):
        print(f"  shares ~ partner mass ** {power:<4g}      {chain_sweep_radius(masses, partner_shares(masses, power)):.8f}")
    radius, lows = best_grid_shares(masses)
    print(f"  best of a grid of shares           {radius:.8f} (lower-contact shares {', '.join(f'{w:.2f}' for w in lows)})")


# ----------------------------------------------------------------------------- the scan
def run_scan(args) -> None:
    from sandbox import Scene, Settings, World
    from sandbox.errors import SimulationError
    from sandbox.scene.library import resolve_scene

    scene = Scene.load(resolve_scene(args.scene))
    print(f"{args.scene}, {args.steps} steps, stability limit off: mean KE of the last 60 frames, peak speed, "
          "top body's displacement")
    for solver in args.solvers.split(","):
        for k in (int(x) for x in args.iterations.split(",")):
            for hz in (float(x) for x in args.hertz.split(",")):
                settings = Settings(contact_hertz=hz, contact_stiffness_limit=0.0)
                world = World(scene, solver=solver, iterations=k, arch="cpu", settings=settings)
                start = world.state()["position"]
                top = int(np.argmax(start[:, 2]))
                energy, peak, note = [], 0.0, ""
                try:
                    for _ in range(args.steps):
                        world.step(1)
                        energy.append(world.metrics()["kinetic_energy"])
                        v = world.state(["linear_velocity"])["linear_velocity"]
                        peak = max(peak, float(np.linalg.norm(v, axis=1).max()))
                except SimulationError:
                    note = "  diverged"
                moved = float(np.linalg.norm(world.state()["position"][top] - start[top]))
                world.close()
                ke = float(np.mean(energy[-60:])) if energy else float("nan")
                print(f"{solver:22s} {k:3d} it {hz:5.1f} Hz  KE {ke:9.2e} J  peak {peak:6.2f} m/s  "
                      f"top {moved:6.3f} m{note}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    model = sub.add_parser("model", help="spectral radius of the linear column model")
    model.add_argument("--boxes", type=int, default=20)
    model.add_argument("--iterations", default="1,2,4,8,15,30")
    buckling = sub.add_parser("buckling", help="the column's critical spring against each schedule's cap")
    buckling.add_argument("--boxes", type=int, default=20)
    buckling.add_argument("--iterations", default="1,2,4,8,15,30")
    split = sub.add_parser("split-weights", help="a heavy-on-light chain's convergence per sweep, any mass split")
    split.add_argument("--masses", default="1,10,100,1000", help="bottom to top [kg]")
    scan = sub.add_parser("scan", help="the engine with the stability limit off")
    scan.add_argument("scene", nargs="?", default="pyramid_20")
    scan.add_argument("--steps", type=int, default=300)
    scan.add_argument("--solvers", default="pgs,mass-splitting,block-mass-splitting")
    scan.add_argument("--iterations", default="1,2,4,8,15,30")
    scan.add_argument("--hertz", default="5,10,15,20,30,45,60")
    args = ap.parse_args()
    {"model": run_model, "buckling": run_buckling, "split-weights": run_split_weights, "scan": run_scan}[args.what](args)


if __name__ == "__main__":
    main()
