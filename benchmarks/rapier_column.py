"""A tall column of boxes on the contact spring alone, in our engine and in Rapier: how soft a spring
each holds, and whether Rapier's holds by its contact forces (docs/method-notes.md, "The column
beside Rapier, re-examined").

    python benchmarks/rapier_column.py thresholds [--boxes 5,20] [--iterations 4] [--seconds 30]  # ~1 min
    python benchmarks/rapier_column.py torque [--iterations 4] [--shipped]                        # ~30 s
    python benchmarks/rapier_column.py balance [--columns 3:4,5:4.5,20:15]                        # ~30 s

Every run compares the contact spring and nothing else: ours is serial PGS with the stability limit,
the rocking share, the load stiffening and the preload off and one sweep of each kind per substep
(``SPRING_ONLY``), Rapier 0.36 (``sandbox.peers.RapierWorld``, one thread) has its dynamic and static
contact springs both at the frequency asked for (its default makes the static one twice as stiff),
damping ratio 10 in both. Boxes are unit cubes of 1000 kg (``sandbox.hard_cases``).

``thresholds``: the nudged column (``hard_cases.nudged_stack``: the top box pushed at 1 mm/s at 0.5 s)
at contact frequencies around the elastic column's critical one (``stiffness_limit.critical_omega``:
the springs at a face's corners as rotational springs, the weight above as the P-Delta load; Greenhill's
self-weight buckling for a column of joints). Per cell: the largest sideways offset of any box over the
last 10 s of the run [mm]; "fell" past 0.5 m.

``torque``: three boxes, a torque of 2000 N m about y on the middle one for 5 s: the middle box's turn
relative to the bottom one each second against the static answer T / k_r (k_r = m omega^2 / 8, the
four corner springs of a 1000 kg pair about the face's middle), ours with one and with eight sweeps of
each kind per substep, and Rapier. ``--shipped``: also ours with its shipped settings (load-stiffened,
preloaded springs: no longer the same spring, so only whether the turn settles compares), serial PGS
and mass splitting at 4, 8 and 15 iterations, for 10 s.

``balance``: Rapier alone. A leaning column after 30 s, averaged over 60 steps: the moment about y of
the weights above the lowest box-box joint against the moment of that joint's normal impulses (as
Rapier reports them per point) applied at the points' midpoint, then at the upper body's own anchor
with the couples (p2 - p1) x F of the joints above added (Rapier keeps one anchor per body; a force
pair applied at two points that are not on one line is a couple). In rigid-body statics the first sum
is zero. Rapier's per-point impulses leave its patch friction (the default friction model) out.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from sandbox import Scene, World  # noqa: E402
from sandbox.hard_cases import nudged_stack  # noqa: E402
from sandbox.settings import Settings  # noqa: E402
from stiffness_limit import critical_omega  # noqa: E402

SPRING_ONLY = dict(contact_stiffness_limit=0.0, contact_rocking_stiffness=0.0, contact_preload=0.0,
                   contact_deflection=0.0, step_sweeps=0)
FELL = 0.5  # [m] sideways: a column that far out has fallen
ZETA = Settings().contact_damping_ratio  # Rapier's springs take ours


def our_world(scene: Scene, iterations: int, sweeps: int = 1) -> World:
    settings = Settings().replace(**scene.world.settings_given()).replace(sweeps=sweeps, **SPRING_ONLY)
    return World(scene, solver="pgs", iterations=iterations, settings=settings)


def rapier_world(scene: Scene, iterations: int, hertz: float):
    import rapier3d as r

    from sandbox.peers import RapierWorld

    world = RapierWorld(scene, iterations, 1)
    params = world.world.integration_parameters
    params.contact_softness = r.SpringCoefficients(natural_frequency=hertz, damping_ratio=ZETA)
    params.static_contact_softness = r.SpringCoefficients(natural_frequency=hertz, damping_ratio=ZETA)
    return world


def column_scene(boxes: int, hertz: float, nudge: bool) -> tuple[Scene, float]:
    """The nudged column with its springs at ``hertz``; the nudge's impulse [N s] (0 without its event)."""
    case = nudged_stack(boxes)
    scene = dict(case.scene)
    scene["world"] = dict(scene["world"], contact_hertz=hertz)
    impulse = scene["event"][0]["impulse"][0]
    if not nudge:  # Rapier's adapter takes no timeline: the nudge is applied by hand at the same step
        scene.pop("event")
    return Scene.from_dict(scene, source=case.name), impulse


def lean(positions: np.ndarray, start: np.ndarray) -> float:
    return float(np.linalg.norm(positions[:, :2] - start[:, :2], axis=1).max())


def run_column(engine: str, boxes: int, hertz: float, iterations: int, seconds: float) -> float:
    """The largest sideways offset [m] of any box over the run's last 10 s."""
    scene, impulse = column_scene(boxes, hertz, nudge=engine == "ours")
    steps = int(round(seconds / scene.world.dt))
    nudge_step = int(round(0.5 / scene.world.dt))
    worst = 0.0
    if engine == "ours":
        world = our_world(scene, iterations)
        try:
            start = world.state()["position"]
            for k in range(steps):
                world.step(1)
                if k >= steps - int(round(10.0 / scene.world.dt)):
                    worst = max(worst, lean(world.state(("position",))["position"], start))
        finally:
            world.close()
        return worst
    world = rapier_world(scene, iterations, hertz)
    try:
        read = lambda: np.array([world.position(i) for i in range(boxes)])  # noqa: E731
        start = read()
        top = world.world.rigid_bodies[world.handles[boxes - 1]]
        for k in range(steps):
            if k == nudge_step:
                top.apply_impulse((float(impulse), 0.0, 0.0), True)
            world.step()
            if k >= steps - int(round(10.0 / scene.world.dt)):
                worst = max(worst, lean(read(), start))
    finally:
        world.close()
    return worst


def run_thresholds(args) -> None:
    print(f"nudged column, serial PGS with the spring alone against Rapier (1 thread), {args.iterations} iterations, "
          f"{args.seconds:g} s: the largest sideways offset over the last 10 s [mm] ('fell': past {FELL:g} m)")
    for boxes in (int(x) for x in args.boxes.split(",")):
        critical = critical_omega(boxes, 1.0) / (2.0 * math.pi)
        print(f"\n{boxes} boxes: the elastic column's critical spring {critical:.1f} Hz")
        print(f"{'hertz':>7s} {'x critical':>10s} {'ours':>10s} {'Rapier':>10s}")
        for factor in (0.25, 0.35, 0.5, 0.7, 1.0, 1.4):
            hertz = round(critical * factor, 1)
            cells = []
            for engine in ("ours", "rapier"):
                worst = run_column(engine, boxes, hertz, args.iterations, args.seconds)
                cells.append("fell" if worst > FELL else f"{1e3 * worst:.1f}")
            print(f"{hertz:7.1f} {factor:10.2f} {cells[0]:>10s} {cells[1]:>10s}", flush=True)


def turn_y(quaternion_wxyz) -> float:
    """The rotation about y [rad] of a unit quaternion (w, x, y, z), small angles."""
    w, x, y, z = quaternion_wxyz
    return 2.0 * math.atan2(y, w)


def run_torque(args) -> None:
    hertz, torque = 15.0, 2000.0
    scene, _ = column_scene(3, hertz, nudge=False)
    dt = scene.world.dt
    mass = scene.bodies[1].mass
    inertia = mass / 6.0  # a unit cube about an axis through its centre
    static = torque / (mass * (2.0 * math.pi * hertz) ** 2 / 8.0)
    print(f"three {mass:g} kg boxes, {hertz:g} Hz springs, {torque:g} N m about y on the middle box from t = 0: "
          f"its turn relative to the bottom box [urad] each second; the static answer is {1e6 * static:.0f} urad")

    def report(name, step, turns, seconds=5):
        for k in range(300):
            step(0.0)
        t0 = turns()
        row = []
        for k in range(60 * seconds):
            step(torque)
            if (k + 1) % 60 == 0:
                t = turns() - t0
                row.append(f"{1e6 * (t[1] - t[0]):8.0f}")
        print(f"{name:34s}" + "".join(row), flush=True)

    def report_ours(name, world, seconds=5):
        """``report`` on one of our worlds: the torque as a change of the middle box's spin each step."""
        def step(t):
            if t:
                spin = world.state(("angular_velocity",))["angular_velocity"][1]
                world.set_velocity([1], angular=list(spin + np.array([0.0, t * dt / inertia, 0.0])))
            world.step(1)

        def turns():
            return np.array([turn_y(q) for q in world.state(("orientation",))["orientation"]])

        try:
            report(name, step, turns, seconds)
        finally:
            world.close()

    for sweeps in (1, 8):
        report_ours(f"ours, {sweeps} + {sweeps} sweeps", our_world(scene, args.iterations, sweeps))
    if args.shipped:
        for solver in ("pgs", "mass-splitting"):
            for iterations in (4, 8, 15):
                report_ours(f"ours shipped, {solver} @{iterations}", World(scene, solver=solver, iterations=iterations),
                            seconds=10)
    rapier = rapier_world(scene, args.iterations, hertz)
    bodies = rapier.world.rigid_bodies
    try:
        def step(t):
            if t:
                bodies[rapier.handles[1]].apply_torque_impulse((0.0, t * dt, 0.0), True)
            rapier.step()

        def turns():
            out = []
            for h in rapier.handles:
                q = bodies[h].rotation
                out.append(turn_y((q.w, q.i, q.j, q.k)))
            return np.array(out)

        report("Rapier, 1 + 1 sweeps", step, turns)
    finally:
        rapier.close()


def joint_records(world) -> dict:
    """Per joint height (rounded to 0.1 m): (midpoint, anchor on body 1, anchor on body 2, force on body 2 [N])."""
    out = {}
    dt = world.world.integration_parameters.dt
    for n, p1, p2, impulse in world.contact_points():
        if impulse != 0.0:
            out.setdefault(round(0.5 * (p1[2] + p2[2]), 1), []).append((0.5 * (p1 + p2), p1, p2, impulse / dt * n))
    return out


def moment_y(points: np.ndarray, forces: np.ndarray) -> float:
    return float(np.sum(points[:, 2] * forces[:, 0] - points[:, 0] * forces[:, 2]))


def run_balance(args) -> None:
    print("Rapier's leaning column after 30 s, averaged over 60 steps: moments about y [N m] on the boxes above the "
          "lowest box-box joint")
    print(f"{'boxes':>5s} {'hertz':>6s} {'weights':>9s} {'joint, midpoint':>16s} {'sum':>8s} {'own anchors':>12s}")
    for column in args.columns.split(","):
        boxes, hertz = int(column.split(":")[0]), float(column.split(":")[1])
        scene, impulse = column_scene(boxes, hertz, nudge=False)
        world = rapier_world(scene, 4, hertz)
        try:
            top = world.world.rigid_bodies[world.handles[boxes - 1]]
            for k in range(1800):
                if k == 30:
                    top.apply_impulse((float(impulse), 0.0, 0.0), True)
                world.step()
            rows = []
            for k in range(60):
                world.step()
                x = np.array([world.position(i) for i in range(boxes)])
                weight = scene.bodies[0].mass * -scene.world.gravity[2]  # [N] of each box
                weights = float(np.sum(x[1:, 0]) * weight)  # M_y of -W z at x: x W
                joints = joint_records(world)
                lowest = min(z for z in joints if z > 0.5)
                mid = np.array([j[0] for j in joints[lowest]])
                upper = np.array([j[2] for j in joints[lowest]])
                forces = np.array([j[3] for j in joints[lowest]])
                couples = sum(moment_y(np.array([j[2] - j[1]]), np.array([j[3]]))
                              for z in joints if z > lowest + 0.05 for j in joints[z])
                rows.append((weights, moment_y(mid, forces), moment_y(upper, forces) + couples))
            w, m, own = np.mean(rows, axis=0)
            print(f"{boxes:5d} {hertz:6.1f} {w:9.1f} {m:16.1f} {w + m:8.1f} {w + own:12.1f}", flush=True)
        finally:
            world.close()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    t = sub.add_parser("thresholds", help="the column's standing spring, ours against Rapier")
    t.add_argument("--boxes", default="5,20")
    t.add_argument("--iterations", type=int, default=4)
    t.add_argument("--seconds", type=float, default=30.0)
    q = sub.add_parser("torque", help="three boxes under a torque: the static answer reached or not")
    q.add_argument("--iterations", type=int, default=4)
    q.add_argument("--shipped", action="store_true", help="also ours with its shipped settings, 4, 8 and 15 iterations")
    b = sub.add_parser("balance", help="Rapier's leaning column: its contact moments against the weights'")
    b.add_argument("--columns", default="3:4,5:4.5,20:15", help="boxes:hertz, comma-separated")
    args = p.parse_args(argv)
    {"thresholds": run_thresholds, "torque": run_torque, "balance": run_balance}[args.what](args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
