"""How long the web sandbox's world pauses after each panel action that may compile kernels.

    python benchmarks/panel_actions.py [--scene playground] [--steps 3]

Builds the scene's world as the web sandbox does (``web.simulation.web_world``: debris kinds
reserved, ``prepare_edits``, the sampled step timed launch by launch), steps it past its first steps, then
applies the panel's effect toggles and solver switches one after another, as events between
steps, and prints the wall time of each of the next ``--steps`` steps, a ``World.metrics()`` read
included (the panel reads one per published snapshot). A first step of seconds is a compile (new
kernel instances) or a load from Taichi's kernel cache: run it twice to tell a cold cache from a
warm one. No browser and no server: what the simulation thread itself pays.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")

EFFECT_TOGGLES = (("friction", "restitution"), ("restitution",), ("friction", "restitution"),
                  ("friction", "restitution", "sleeping"))
"""From the playground's own effects: sleeping off, friction off, friction back, sleeping back."""
SOLVERS = ("pgs", "pgs-colored", "jacobi", "block-mass-splitting", "mass-splitting")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="playground")
    ap.add_argument("--steps", type=int, default=3, help="steps timed after each action")
    args = ap.parse_args()

    from sandbox import Scene
    from sandbox.scene.library import resolve_scene
    from sandbox.scene.spec import EventSpec
    from web.simulation import web_world

    world = web_world(Scene.load(resolve_scene(args.scene)), "cpu")
    world.step(3)
    world.metrics()
    print(f"# {platform.machine()}, {os.cpu_count()} CPUs; {args.scene}, {world.solver} x {world.iterations}; "
          f"ms of each of the {args.steps} steps after an action (a metrics read included)")

    def timed(label: str) -> None:
        ms = []
        for _ in range(args.steps):
            t = time.perf_counter()
            world.step(1)
            world.metrics()
            ms.append(1e3 * (time.perf_counter() - t))
        print(f"{label:48s} {'  '.join(f'{x:8.0f}' for x in ms)}", flush=True)

    timed("(none)")
    for effects in EFFECT_TOGGLES:
        world.apply_event(EventSpec(time=world.step_count * world.dt, kind="effects", effects=effects))
        timed(f"effects {', '.join(effects)}")
    for solver in SOLVERS:
        world.apply_event(EventSpec(time=world.step_count * world.dt, kind="solver", solver=solver))
        timed(f"solver {solver}")


if __name__ == "__main__":
    main()
