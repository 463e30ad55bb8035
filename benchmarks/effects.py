"""What each optional effect costs (issue 16): one world per effect variant of a scene, in one
process, each run from the same start; writes the table to docs/effects.md (--write).

    PYTHONPATH=$PWD python benchmarks/effects.py [--scenes pile_1000,playground] [--settle 120]
                                                 [--steps 60] [--write]

Variants: the scene as shipped; each effect it has switched off (friction, restitution,
sleeping) or on (sleeping); the gyroscopic step flipped (the host flag: on for a scene whose
bodies do not need it, off for one whose bodies do, so its cost shows either way; the
motion of the latter is then wrong, only its time counts); every body given damping
(0.1 / s, linear and angular) or rolling and torsional friction (5 mm lever arms); and
speculative contacts off. Every world steps ``--settle``
steps untimed (compiling its kernels), then ``--steps`` timed one by one (synchronised); the
median is reported, since a kernel compiled on first use inside the timed steps (the first
island to fall asleep) would dominate a mean. Each variant changes the
motion where the effect acts (a frictionless pile spreads), so the contact count is printed
beside the time. CPU figures on a shared machine are one run's: compare them as ratios.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import taichi as ti

from sandbox import Scene, Settings, World, resolve_scene

DOC = Path(__file__).resolve().parent.parent / "docs" / "effects.md"


@dataclass(frozen=True)
class Variant:
    label: str
    effects: tuple
    flip_gyroscopic: bool = False
    bodies: tuple = ()  # (key, value) set on every dynamic body (scene.spec.RESISTANCE_KEYS)
    settings: tuple = ()  # (key, value) of settings.Settings


def variants(shipped: tuple) -> list[Variant]:
    """The variants of a scene shipped with the effects ``shipped``."""
    out = [Variant("as shipped", shipped)]
    for effect in ("friction", "restitution", "sleeping"):
        if effect in shipped:
            out.append(Variant(f"without {effect}", tuple(e for e in shipped if e != effect)))
    if "sleeping" not in shipped:
        out.append(Variant("with sleeping", shipped + ("sleeping",)))
    out.append(Variant("gyroscopic step flipped", shipped, flip_gyroscopic=True))
    out.append(Variant("with damping", shipped, bodies=(("linear_damping", 0.1), ("angular_damping", 0.1))))
    out.append(Variant("with rolling friction", shipped,
                       bodies=(("rolling_friction", 0.005), ("torsional_friction", 0.005))))
    out.append(Variant("without speculative contacts", shipped, settings=(("speculative_contacts", False),)))
    return out


def run(scene_name: str, variant: Variant, settle: int, steps: int) -> dict:
    scene = Scene.load(resolve_scene(scene_name))
    if variant.bodies:
        changed = [dataclasses.replace(b, **dict(variant.bodies)) if not b.static else b for b in scene.bodies]
        scene = dataclasses.replace(scene, bodies=changed)
    world = World(scene, arch="cpu", settings=Settings().replace(**scene.world.settings_given(),
                                                                 **dict(variant.settings)))
    world.set_effects(variant.effects)
    flip_gyroscopic = variant.flip_gyroscopic
    if flip_gyroscopic:  # the benchmark's switch: on where no body needs it, off where some do
        world._edits.host.has_gyroscopic = not world._edits.host.has_gyroscopic
    world.step(settle)
    times = []
    for _ in range(steps):
        ti.sync()
        t0 = time.perf_counter()
        world.step(1)
        ti.sync()
        times.append(time.perf_counter() - t0)
    ms = 1e3 * float(np.median(times))  # a kernel compiled on first use (say, the first island to sleep) is an outlier
    m = world.metrics()
    row = {"ms": ms, "contacts": m["contacts"], "awake": m["awake_bodies"],
           "bodies": m["awake_bodies"] + m["sleeping_bodies"],
           "compiled": world.compiled_effects.as_dict(), "solver": f"{world.solver} x {world.iterations}"}
    world.close()
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="pile_1000,playground")
    ap.add_argument("--settle", type=int, default=120)
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--write", action="store_true", help="write docs/effects.md's measured table")
    args = ap.parse_args()
    lines = []
    for name in args.scenes.split(","):
        shipped = tuple(Scene.load(resolve_scene(name)).effects)
        base = None
        for variant in variants(shipped):
            label = variant.label
            row = run(name, variant, args.settle, args.steps)
            base = base or row["ms"]
            on = ", ".join(k for k, v in row["compiled"].items() if v) or "none"
            line = (f"| {name} | {label} | {on} | {row['ms']:.2f} | {100 * row['ms'] / base:.0f} % | "
                    f"{row['contacts']} | {row['awake']} of {row['bodies']} |")
            print(line, row["solver"], flush=True)
            lines.append(line)
    load = os.getloadavg()
    footer = (f"Measured {time.strftime('%Y-%m-%d')} on {platform.processor() or platform.machine()}, "
              f"{os.cpu_count()} CPUs, Taichi CPU backend, one run (load average {load[0]:.2f}); "
              f"each world stepped {args.settle} steps untimed, then {args.steps} timed: "
              f"`PYTHONPATH=$PWD python benchmarks/effects.py --write`.")
    print(footer)
    if args.write:
        text = DOC.read_text()
        start, end = text.index("<!-- table -->"), text.index("<!-- /table -->")
        table = ("| scene | variant | compiled in | median ms/step | vs shipped | contacts | awake bodies |\n"
                 "|---|---|---|--:|--:|--:|--:|\n" + "\n".join(lines) + "\n\n" + footer + "\n")
        DOC.write_text(text[:start] + "<!-- table -->\n" + table + text[end:])


if __name__ == "__main__":
    main()
