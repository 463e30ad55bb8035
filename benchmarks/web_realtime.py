"""How fast the web sandbox's simulation runs against real time, before and after a debris drop.

    python benchmarks/web_realtime.py [--scene playground] [--steps 300] [--count 20] [--mix mixed]
                                      [--drops 1] [--solver ...] [--iterations ...]

Runs the web app as ``sandbox serve`` does (web/app.py: the viser server, the render thread
drawing every new snapshot at up to 30 Hz, and the simulation thread with its once-per-window
profiled step and the snapshots it publishes) on the CPU, with the simulation's real-time
pacing off so that it steps as fast as it can; no browser is attached (what a browser's frames
cost is ``benchmarks/web_frame_bench.py``'s). Prints, from the tenth step on and from each drop
(the same drop as the panel's "Drop debris" button, timed from the step at which it
is applied), steps/s, the real-time factor (simulated seconds per wall second) and the body
count over the next ``--steps`` steps: the first simulated seconds of the scene (its bodies
falling, once the kernels are compiled) and of each drop (debris falling onto the heap), the
part of a session that costs most; the playground's settled parts sleep, as shipped.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")


def window(sim, steps: int, timeout: float = 600.0) -> tuple[float, float, int, float]:
    """(steps/s, real-time factor, bodies, simulated seconds) over the next ``steps`` steps."""
    world = sim.world
    s0, t0 = world.step_count, time.perf_counter()
    while world.step_count < s0 + steps and time.perf_counter() < t0 + timeout:
        time.sleep(0.002)
    s1, t1 = world.step_count, time.perf_counter()
    rate = (s1 - s0) / (t1 - t0)
    return rate, rate * world.dt, world.body_count, (s1 - s0) * world.dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="playground")
    ap.add_argument("--steps", type=int, default=300, help="steps timed from the start and from each drop")
    ap.add_argument("--count", type=int, default=20, help="bodies per drop (the panel's default)")
    ap.add_argument("--mix", default="mixed")
    ap.add_argument("--drops", type=int, default=1)
    ap.add_argument("--solver", default=None, help="default: the app's (mass-splitting)")
    ap.add_argument("--iterations", type=int, default=None, help="default: the app's (15)")
    a = ap.parse_args()
    from sandbox import EventSpec
    from web.app import SandboxApp, free_port
    from web.debris import debris_bodies

    slow = []
    app = SandboxApp(a.scene, port=free_port(), arch="cpu", solver=a.solver or "mass-splitting",
                     iterations=a.iterations or 15,
                     log=lambda line, **kw: slow.append(line) if "slow step" in line else None)
    sim = app.sim
    sim.realtime = False
    app.start(background=True)
    deadline = time.perf_counter() + 600.0
    while sim.world.step_count < 10 and time.perf_counter() < deadline:  # the first steps compile, the
        time.sleep(0.1)  # third (the stats window's profiled step) its per-stage launches too
    w = sim.world
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; {a.scene}, {w.solver}, "
          f"{w.iterations} iterations, dt {w.dt:.4f} s, real-time pacing off")
    rate, factor, bodies, simulated = window(sim, a.steps)
    print(f"start (steps 10+)  {rate:7.1f} steps/s  {factor:5.2f}x real time  {bodies} bodies  "
          f"over {simulated:.1f} s simulated", flush=True)
    for k in range(a.drops):
        def run(s, seed=k + 1):
            s.apply(EventSpec(time=0.0, kind="drop",
                              new_bodies=debris_bodies(s.latest(), a.count, a.mix, seed)))
        before = sim.world.body_count
        sim.submit(f"drop {a.count} {a.mix}", run)
        while sim.world.body_count == before:
            time.sleep(0.001)
        rate, factor, bodies, simulated = window(sim, a.steps)
        print(f"drop {k + 1}            {rate:7.1f} steps/s  {factor:5.2f}x real time  {bodies} bodies  "
              f"over {simulated:.1f} s simulated", flush=True)
    app.stop()
    for line in slow:
        print(line)


if __name__ == "__main__":
    main()
