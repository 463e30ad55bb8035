"""The bench's outputs other than plots: the machine it ran on, the derived tables (peer
ratios, cost fits), JSON-safe numbers, the CSV files and the printed summary."""

from __future__ import annotations

import csv
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

from .protocol import REFERENCE_PEER, finite

REPO = Path(__file__).resolve().parent.parent.parent


def machine() -> dict:
    """What the numbers were measured on: CPU, memory, load at the start, versions, git commit."""
    info = {"platform": platform.platform(), "python": platform.python_version(), "cpu_count": os.cpu_count()}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                info["memory_gb"] = round(int(line.split()[1]) / 2**20, 1)
                break
    except OSError:
        pass
    info.setdefault("cpu", platform.processor() or platform.machine())
    try:
        info["load_average_at_start"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass
    try:
        from importlib.metadata import version

        info["taichi"] = version("taichi")
        info["numpy"] = version("numpy")
    except Exception:
        pass
    try:
        info["git"] = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"], capture_output=True,
                                     text=True, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        info["git"] = None
    return info



# ---------------------------------------------------------------------------------------------- tables
def add_peer_ratios(rows: list[dict]) -> None:
    ref = {(r["scene"], r["iterations"]): r for r in rows if r["engine"] == REFERENCE_PEER and r["status"] == "ok"}
    for r in rows:
        p = ref.get((r["scene"], r["iterations"]))
        if r["engine"] != "sandbox" or p is None or r["status"] != "ok":
            continue
        if p["steps_per_s"]:
            r["steps_per_s_ratio_to_pybullet"] = r["steps_per_s"] / p["steps_per_s"]
        if p["kinetic_energy"]:
            r["kinetic_energy_ratio_to_pybullet"] = r["kinetic_energy"] / p["kinetic_energy"]


def cost_fits(rows: list[dict]) -> list[dict]:
    """Least-squares t(k) = t0 + k t1 of ms/step over the iteration counts (method.md 3):
    t0 is the per-step cost (collision, set-up), t1 the cost of one iteration (substep)."""
    groups: dict = {}
    for r in rows:
        if r["status"] == "ok" and r["ms_per_step"] is not None:
            groups.setdefault((r["scene"], r["engine"], r["solver"], r["options"]), []).append(r)
    fits = []
    for (scene, engine, solver, options), rs in groups.items():
        ks = np.array([r["iterations"] for r in rs], dtype=float)
        if len(set(ks)) < 2:
            continue
        t = np.array([r["ms_per_step"] for r in rs])
        t1, t0 = np.polyfit(ks, t, 1)
        fits.append({"scene": scene, "engine": engine, "solver": solver, "options": options,
                     "t0_ms": float(t0), "t1_ms_per_iteration": float(t1)})
    return fits


def significant(v, digits: int = 5):
    v = finite(v)
    return None if v is None else float(f"{v:.{digits}g}")


def json_safe(value):
    if isinstance(value, float):
        return finite(value)
    if isinstance(value, (np.floating, np.integer)):
        return json_safe(value.item())
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def write_csv(path: Path, columns, rows) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow(["" if r.get(c) is None else (f"{r[c]:.6g}" if isinstance(r[c], float) else r[c])
                        for c in columns])



def _fmt(v, spec):
    digits = "".join(ch for ch in spec.split(".")[0] if ch.isdigit())
    width = int(digits or 0)
    return "-".rjust(width) if v is None else format(v, spec)


def print_summary(doc, cfg, out, pngs, echo) -> None:
    meta = doc["meta"]
    m = meta["machine"]
    echo(f"# {m.get('cpu')} ({m.get('cpu_count')} cores), arch {meta['arch']}, taichi {m.get('taichi')}, "
         f"pybullet {meta['pybullet'] or '-'}; settle {cfg['settle']}, window {cfg['window']}, "
         f"timed {cfg['steps']} steps; {meta['wall_s']:.0f} s")

    def label(r):
        return r["solver"] + ("+" + r["options"] if r["options"] else "")

    ws = max([12] + [len(r["scene"]) for r in doc["rows"]])
    wl = max([20] + [len(label(r)) for r in doc["rows"] + doc["scaling"]])
    echo(f"{'scene':{ws}s} {'solver':{wl}s} {'it':>4s} {'contacts':>8s} {'ms/step':>8s} {'steps/s':>8s} "
         f"{'ms/iter':>8s} {'KE [J]':>9s} {'pen max':>9s} {'res rms':>9s} {'frozen':>9s} {'drift':>9s} "
         f"{'x pb s/s':>8s} {'x pb KE':>8s}")
    for r in doc["rows"]:
        if r["status"] != "ok":
            echo(f"{r['scene']:{ws}s} {label(r):{wl}s} {r['iterations']:4d} {r['status']}")
            continue
        echo(f"{r['scene']:{ws}s} {label(r):{wl}s} {r['iterations']:4d} {r['contacts']:8d} {r['ms_per_step']:8.2f} "
             f"{r['steps_per_s']:8.1f} {_fmt(r['ms_per_iteration'], '8.3f')} {r['kinetic_energy']:9.2e} "
             f"{r['max_penetration']:9.2e} {_fmt(r['residual_rms'], '9.2e')} {_fmt(r['frozen_residual'], '9.2e')} "
             f"{_fmt(r['drift'], '9.2e')} {_fmt(r['steps_per_s_ratio_to_pybullet'], '8.3g')} "
             f"{_fmt(r['kinetic_energy_ratio_to_pybullet'], '8.1e')}")
    for f in doc["cost_fits"]:
        echo(f"cost fit   {f['scene']:{ws}s} {label(f):{wl}s} "
             f"t(k) = {f['t0_ms']:.2f} ms + k x {f['t1_ms_per_iteration']:.3f} ms")
    for r in doc["scaling"]:
        if r["status"] == "ok":
            echo(f"scaling    {r['bodies']:5d} bodies {_fmt(r['contacts'], '6d')} contacts  "
                 f"{label(r):{wl}s} {r['ms_per_step']:8.2f} ms/step")
        else:
            echo(f"scaling    {r['bodies']:5d} bodies {label(r):{wl}s} {r['status']}")
    echo(f"wrote      {out / 'bench.csv'}, {out / 'bench.json'}, {out / 'scaling.csv'}, "
         f"{len(pngs)} PNGs in {out}")
