"""What the panel's text and plots show of a snapshot: the stats table, the paused step's
description, and series in decades (the plots' y axis). Pure functions of published data, so
the panel only places them.
"""

from __future__ import annotations

import numpy as np

LOG_FLOOR = -12.0
"""Decades below which the plots show nothing (a resting pile's energy reaches ~1e-10 J)."""


def decades(values: np.ndarray) -> np.ndarray:
    """log10 of a plotted series, floored at LOG_FLOOR (zero energy, a step without contacts)."""
    return np.log10(np.maximum(values, 10.0 ** LOG_FLOOR))


def stats_table(snap, render_fps: float, window_s: float) -> str:
    """The Stats folder's table: counts, speed, timings (saying what each measures), energy."""
    m, t = snap.metrics, snap.timing_ms
    stages = " · ".join(f"{k} {t.get(k, 0.0):.2f}" for k in ("collide", "solve"))
    lines = [
        "| | |\n|---|---|",
        f"| bodies | **{len(snap.bodies)}** |",
        f"| contacts | {m['contacts']} ({m['manifolds']} manifolds) |",
        f"| awake / asleep | {m['awake_bodies']} / {m['sleeping_bodies']} bodies, {m['islands']} islands |",
    ]
    if "colors" in m:
        lines.append(f"| colours | {m['colors']} |")
    lines += [
        f"| step | {snap.step} (t = {snap.step * snap.dt:.2f} s) |",
        f"| sim | {snap.steps_per_second:.1f} steps/s ({snap.realtime_factor:.2f}× real time) |",
        f"| render | {render_fps:.1f} FPS |",
        f"| ms/step | {t.get('total', 0.0):.2f} (mean of the unprofiled steps) |",
        f"| sampled step [ms] | {stages} (one step per {window_s:g} s, a sync after each of its "
        "launches; solve includes the substeps' integration) |",
        f"| kinetic energy | {m['kinetic_energy']:.3e} J |",
        f"| max penetration | {1e3 * m['max_penetration']:.2f} mm |",
        f"| residual RMS | {m['residual_rms']:.2e} m/s |",
    ]
    return "\n".join(lines)


def inspection_text(view: dict) -> str:
    """The Inside-the-solver folder's text for a paused step (web/snapshot.inspection_view)."""
    c = view["contacts"]
    lines = [f"**{view['label']}**", "",
             f"{len(c['impulse'])} contact points; largest normal impulse {c['impulse'].max(initial=0.0):.3g} N s; "
             f"residual RMS {view['residuals'][-1]:.3g} m/s"]
    sub = view["sub_bodies"]
    if view["body"] is None:
        lines.append("\nSelect a body to see its sub-bodies.")
    elif sub is None:
        lines.append(f"\nBody {view['body']}: no sub-bodies (a static body, or a PGS solver: its rows act on "
                     "the body itself, one after another).")
    else:
        lines += ["", f"Sub-bodies of body {view['body']} (split {sub['split']:.3g}), velocity [m/s]:", "",
                  "| block | v_x | v_y | v_z |", "|---|--:|--:|--:|"]
        for block, v in zip(sub["blocks"], sub["linear"]):
            lines.append(f"| {block} | {v[0]:.4g} | {v[1]:.4g} | {v[2]:.4g} |")
        merged = sub["merged"][0]
        lines.append(f"| **merged** | {merged[0]:.4g} | {merged[1]:.4g} | {merged[2]:.4g} |")
    return "\n".join(lines)
