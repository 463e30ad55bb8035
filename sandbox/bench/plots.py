"""The bench's PNGs, drawn from a bench document alone (``bench.json`` can be re-plotted without
re-running: ``sandbox.bench.write_plots(json.load(open("bench.json")), "dir")``)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from ..peers import PEERS
from .protocol import series_key, solver_label

ERROR_PANELS = (
    ("residual_rms", "LCP residual RMS, rigid problem [m/s]"),
    ("max_penetration", "max penetration [m]"),
    ("kinetic_energy", "resting kinetic energy [J]"),
    ("drift", "marker drift over the window [m]"),
)


def _row_label(r: dict) -> str:
    """A result row's curve label: the solver, with its options when it has any."""
    return r["solver"] + (f" [{r['options']}]" if r["options"] else "")


def _line_style(label: str) -> dict:
    return dict(ls="--", marker="s") if label in PEERS else dict(ls="-", marker="o")


def _finish_axes(ax, legend_size: int) -> None:
    ax.grid(True, which="both", alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=legend_size)
        _tidy_log_axes(ax)


def _save(plt, fig, path, title: str) -> None:
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _tidy_log_axes(ax) -> None:
    """Plain number labels on log axes; minor labels only where an axis spans less than a decade."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    fmt = FuncFormatter(lambda v, _: f"{v:g}")
    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() != "log":
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lo, hi = sorted(axis.get_view_interval())
        axis.set_major_formatter(fmt)
        axis.set_minor_formatter(fmt if lo > 0 and hi / lo < 10 else NullFormatter())


def _curves(rows, scene):
    out: dict = {}
    for r in rows:
        if r["scene"] == scene and r["status"] == "ok":
            out.setdefault(_row_label(r), []).append(r)
    for rs in out.values():
        rs.sort(key=lambda r: r["iterations"])
    return out


def plot_pareto(plt, rows, scene, path, meta):
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    for ax, (key, title) in zip(axes.flat, ERROR_PANELS):
        for label, rs in _curves(rows, scene).items():
            pts = [(r["ms_per_step"], r[key], r["iterations"]) for r in rs
                   if r[key] is not None and r[key] > 0 and r["ms_per_step"]]
            if not pts:
                continue
            x, y, k = zip(*pts)
            style = _line_style(label)
            ax.plot(x, y, label=label, ms=4, lw=1.2, **style)
            for xi, yi, ki in pts:
                ax.annotate(str(ki), (xi, yi), textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("ms / step (wall, device-synced)")
        zeros = {label: [str(r["iterations"]) for r in rs if r[key] == 0] for label, rs in _curves(rows, scene).items()}
        zeros = "; ".join(f"{label} x{','.join(ks)}" for label, ks in zeros.items() if ks)
        ax.set_title(title + (f"\nexactly 0, not drawn: {zeros}" if zeros else ""), fontsize=9)
        _finish_axes(ax, legend_size=7)
    _save(plt, fig, path, f"{scene}: error vs cost, one point per iteration count (label) - lower left is better\n"
          f"{meta['machine'].get('cpu', '')}, arch {meta['arch']}")


def plot_jitter(plt, rows, series, scene, path, settle):
    ks = sorted({r["iterations"] for r in rows if r["scene"] == scene})
    cols = min(len(ks), 3)
    nrows = math.ceil(len(ks) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols, 3.2 * nrows), squeeze=False, sharex=True)
    for ax, k in zip(axes.flat, ks):
        for r in rows:
            if r["scene"] != scene or r["iterations"] != k:
                continue
            ke = np.asarray([np.nan if v is None else v for v in series.get(series_key(r), [])], dtype=float)
            if len(ke) == 0:
                continue
            label = _row_label(r)
            ax.semilogy(np.arange(1, len(ke) + 1), np.maximum(ke, 1e-12), lw=0.9, label=label,
                        ls="--" if r["engine"] != "sandbox" else "-")
        ax.axvline(settle, color="k", lw=0.6, alpha=0.5)
        ax.set_title(f"{k} iteration{'s' if k != 1 else ''}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel("frame")
        ax.set_ylabel("kinetic energy [J]")
    for ax in list(axes.flat)[len(ks):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    _save(plt, fig, path, f"{scene}: kinetic energy vs frame (no sleeping, no damping); error window right of the line")


def plot_convergence(plt, conv, scene, path):
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for c in conv:
        res = np.asarray([np.nan if v is None else v for v in c["residual"]], dtype=float)
        if not np.any(res > 0):  # no contacts: nothing to converge
            continue
        label = solver_label(c["solver"], c["options"])
        k = np.arange(1, len(res) + 1)
        a.loglog(k, res, lw=1.2, label=label)
        if c["ms_per_sweep"]:
            b.loglog(k * c["ms_per_sweep"], res, lw=1.2, label=label)
    a.set_xlabel("sweeps on the frozen problem (iterations = 1, warm start off)")
    b.set_xlabel("solve time [ms] (sweeps x ms/sweep)")
    for ax in (a, b):
        ax.set_ylabel("RMS residual, biased problem [m/s]")
        _finish_axes(ax, legend_size=8)
    _save(plt, fig, path, f"{scene}: convergence on one frozen step of the settled scene")


def plot_scaling(plt, rows, path, meta):
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    groups: dict = {}
    for r in rows:
        if r["status"] == "ok" and r["ms_per_step"]:
            groups.setdefault(_row_label(r), []).append(r)
    for label, rs in groups.items():
        rs.sort(key=lambda r: r["bodies"])
        style = _line_style(label)
        a.loglog([r["bodies"] for r in rs], [r["ms_per_step"] for r in rs], label=label, ms=4, **style)
        pts = [(r["contacts"], r["ms_per_step"]) for r in rs if r["contacts"]]
        if pts:
            b.loglog(*zip(*pts), label=label, ms=4, **style)
    a.set_xlabel("bodies")
    b.set_xlabel("contact points (after the settle)")
    for ax in (a, b):
        ax.set_ylabel("ms / step")
        _finish_axes(ax, legend_size=8)
    _save(plt, fig, path, f"scaling on grid piles, {meta['scaling_iterations']} iterations, arch {meta['arch']}, "
          f"{meta['machine'].get('cpu', '')}")


def write_plots(doc: dict, out) -> list[Path]:
    """Every PNG from a bench document alone (``bench.json`` can be re-plotted without re-running:
    ``sandbox.bench.write_plots(json.load(open("bench.json")), "dir")``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    meta = doc["meta"]
    settle = meta["config"]["settle"]
    scenes = list(dict.fromkeys(r["scene"] for r in doc["rows"]))
    pngs = []
    for name in scenes:
        pngs.append(out / f"pareto_{name}.png")
        plot_pareto(plt, doc["rows"], name, pngs[-1], meta)
        pngs.append(out / f"jitter_{name}.png")
        plot_jitter(plt, doc["rows"], doc["series_kinetic_energy"], name, pngs[-1], settle)
        pngs.append(out / f"convergence_{name}.png")
        plot_convergence(plt, doc["convergence"].get(name, []), name, pngs[-1])
    if doc["scaling"]:
        pngs.append(out / "scaling.png")
        plot_scaling(plt, doc["scaling"], pngs[-1], meta)
    return pngs

