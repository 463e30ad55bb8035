"""``sandbox bench``'s entry point: the configurations (full and ``--quick``), the loop over
scenes x solvers x iteration counts, the peers, the frozen problems and the scaling piles, and
the files it writes."""

from __future__ import annotations

import json
import time
from pathlib import Path

from ..peers import PEERS
from .experiments import convergence, frozen_problem, grid_pile, run_scaling_point
from .plots import write_plots
from .protocol import COLUMNS, REFERENCE_PEER, SCALING_COLUMNS, run_peer, run_sandbox, series_key
from .report import add_peer_ratios, cost_fits, json_safe, machine, print_summary, significant, write_csv

FULL = {
    "scenes": ("stack_20", "pyramid_20", "pile_1000"),
    "solvers": None,  # every solver in SOLVERS
    "iterations": (1, 2, 4, 8, 15, 30, 60, 120, 250, 500),
    "settle": 120,
    "window": 60,
    "steps": 60,
    "scaling_sizes": (100, 300, 1000, 2000, 5000),
    "scaling_iterations": 15,
}
QUICK = {
    "scenes": ("pyramid_20",),
    "solvers": ("pgs", "mass-splitting"),
    "iterations": (1, 4, 16),
    "settle": 60,
    "window": 30,
    "steps": 30,
    "scaling_sizes": (32, 100),
    "scaling_iterations": 4,
}
"""``--quick``: the 210-box pyramid, the reference and the paper's solver, 1/4/16 iterations, and
two small piles for scaling: a smoke run of every output, within 2 minutes on a 2-core CPU
(``benchmarks/bench_quick_budget.py`` checks that, ``--cold`` from an empty kernel cache)."""


def _options(solver: str, shuffle: bool) -> dict:
    """``--shuffle`` for the solvers that take the option (the registry says which)."""
    from ..solvers import SOLVERS

    return {"shuffle": True} if shuffle and "shuffle" in SOLVERS[solver].defaults else {}


def _reference_peer(wanted: bool):
    """The peer that runs beside our solvers (``REFERENCE_PEER``), or None and why not."""
    if not wanted:
        return None, "peers switched off (--no-peers)"
    peer = PEERS[REFERENCE_PEER]
    ok, why = peer.available()
    return (peer, "") if ok else (None, why)


def resolve_config(quick: bool, **given) -> dict:
    """The configuration of a run: what was given, the rest from ``QUICK`` or ``FULL``."""
    from ..solvers import SOLVERS

    base = QUICK if quick else FULL
    cfg = {k: (given.get(k) if given.get(k) not in (None, [], ()) else base[k]) for k in base}
    cfg["solvers"] = tuple(cfg["solvers"] or SOLVERS)
    for k in ("iterations", "scaling_sizes"):
        cfg[k] = tuple(int(x) for x in cfg[k])
    return cfg


def command_line(cfg: dict, arch: str, out: str, shuffle: bool, peers: bool, scaling: bool) -> str:
    parts = ["sandbox bench", *cfg["scenes"], "--solvers", ",".join(cfg["solvers"]),
             "--iterations", ",".join(map(str, cfg["iterations"])), "--settle", str(cfg["settle"]),
             "--window", str(cfg["window"]), "--steps", str(cfg["steps"]), "--arch", arch]
    if scaling:
        parts += ["--scaling-sizes", ",".join(map(str, cfg["scaling_sizes"])),
                  "--scaling-iterations", str(cfg["scaling_iterations"])]
    else:
        parts.append("--no-scaling")
    if shuffle:
        parts.append("--shuffle")
    if not peers:
        parts.append("--no-peers")
    return " ".join(parts + ["--out", out])


def run(scenes=None, solvers=None, iterations=None, arch: str = "cpu", out="out/bench", quick: bool = False,
        settle=None, window=None, steps=None, scaling_sizes=None, scaling_iterations=None, shuffle: bool = False,
        peers: bool = True, scaling: bool = True, quiet: bool = False, echo=print) -> dict:
    """Run the whole bench, write the tables and plots into ``out``, return the JSON document."""
    from tqdm import tqdm

    from .. import Scene, backend
    from ..errors import SandboxError
    from ..scene.library import resolve_scene
    from ..solvers import SOLVERS

    try:
        import matplotlib  # noqa: F401  (fail before a long run, not after it)
    except ImportError:
        raise SandboxError("sandbox bench draws its plots with matplotlib: pip install -e '.[plots]'") from None
    cfg = resolve_config(quick, scenes=scenes, solvers=solvers, iterations=iterations, settle=settle, window=window,
                         steps=steps, scaling_sizes=scaling_sizes, scaling_iterations=scaling_iterations)
    for s in cfg["solvers"]:
        if s not in SOLVERS:
            raise SandboxError(f"unknown solver {s!r}; choose from {', '.join(SOLVERS)}")
    for key in ("iterations", "scaling_sizes"):
        if any(v < 1 for v in cfg[key]):
            raise SandboxError(f"--{key.replace('_', '-')} must be positive integers, got {cfg[key]}")
    for key in ("settle", "window", "steps", "scaling_iterations"):
        if int(cfg[key]) < 1:
            raise SandboxError(f"--{key.replace('_', '-')} must be >= 1, got {cfg[key]}")
    loaded = [(Path(resolve_scene(name)).stem, Scene.load(resolve_scene(name))) for name in cfg["scenes"]]
    arch = backend.init(arch)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    peer, peer_note = _reference_peer(peers)
    pb_scenes = {}
    for name, scene in loaded:
        ok, why = peer.translatable(scene) if peer else (False, peer_note)
        pb_scenes[name] = ok
        if peer and not ok:
            echo(f"bench: {peer.name} skips {name}: it {why}")
    if not peer:
        echo(f"bench: no {REFERENCE_PEER} rows: {peer_note}")
    ks = cfg["iterations"]
    sweeps = max(ks)
    sizes = cfg["scaling_sizes"] if scaling else ()
    units = (len(loaded) * len(cfg["solvers"]) * (len(ks) + 1) + sum(pb_scenes.values()) * len(ks)
             + len(sizes) * (len(cfg["solvers"]) + (1 if peer else 0)) + len(loaded))
    meta = {
        "command": command_line(cfg, arch, str(out), shuffle, peers, scaling),
        "config": {k: list(v) if isinstance(v, tuple) else v for k, v in cfg.items()},
        "arch": arch, "shuffle": shuffle, "machine": machine(), "scaling_iterations": cfg["scaling_iterations"],
        "pybullet": peer.version() if peer else None, "pybullet_note": peer_note or None,
        "frozen_problem": f"each scene settled {cfg['settle']} frames with pgs at the scene's own iteration count, "
                          f"then one step with iterations=1, Settings(sweeps={sweeps}, warm_start=0), "
                          "record_residuals: RMS residual of the biased problem after every sweep",
        "started": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    rows, series, conv, scaling_rows = [], {}, {}, []
    t_start = time.perf_counter()
    bar = tqdm(total=units, desc="bench", unit="run", disable=quiet)
    for name, scene in loaded:
        for solver in cfg["solvers"]:
            options = _options(solver, shuffle)
            for k in ks:
                bar.set_postfix_str(f"{name} {solver} x{k}")
                row, ke = run_sandbox(scene, name, solver, options, k, arch, cfg["settle"], cfg["window"],
                                      cfg["steps"])
                rows.append(row)
                series[series_key(row)] = ke
                bar.update()
        if pb_scenes[name]:
            for k in ks:
                bar.set_postfix_str(f"{name} {peer.name} x{k}")
                row, ke = run_peer(peer, scene, name, k, cfg["settle"], cfg["window"], cfg["steps"])
                rows.append(row)
                series[series_key(row)] = ke
                bar.update()
        bar.set_postfix_str(f"{name} frozen problem")
        frozen, settings = frozen_problem(scene, arch, cfg["settle"])
        bar.update()
        conv[name] = []
        for solver in cfg["solvers"]:
            bar.set_postfix_str(f"{name} {solver} convergence")
            options = _options(solver, shuffle)
            c = convergence(frozen, settings, solver, options, sweeps, arch)
            conv[name].append(c)
            for row in rows:
                if (row["scene"], row["engine"], row["solver"]) == (name, "sandbox", solver) \
                        and row["iterations"] <= len(c["residual"]):
                    row["frozen_residual"] = c["residual"][row["iterations"] - 1]
            bar.update()
    for n in sizes:
        scene = Scene.from_dict(grid_pile(n), source=f"<bench scaling pile {n}>")
        for solver in cfg["solvers"]:
            bar.set_postfix_str(f"scaling {len(scene.bodies)} bodies, {solver}")
            scaling_rows.append(run_scaling_point(scene, n, "sandbox", solver, _options(solver, shuffle),
                                                  cfg["scaling_iterations"], arch, cfg["settle"], cfg["steps"]))
            bar.update()
        if peer:
            bar.set_postfix_str(f"scaling {len(scene.bodies)} bodies, {peer.name}")
            scaling_rows.append(run_scaling_point(scene, n, peer.name, peer.name, {}, cfg["scaling_iterations"],
                                                  "cpu", cfg["settle"], cfg["steps"], peer=peer))
            bar.update()
    bar.close()
    add_peer_ratios(rows)
    meta["wall_s"] = time.perf_counter() - t_start
    for curves in conv.values():  # per-frame and per-sweep series to 5 significant digits (file size)
        for c in curves:
            c["residual"] = [significant(v) for v in c["residual"]]
    series = {key: [significant(v) for v in values] for key, values in series.items()}
    doc = json_safe({"meta": meta, "columns": list(COLUMNS), "rows": rows, "cost_fits": cost_fits(rows),
                  "convergence": conv, "scaling": scaling_rows, "series_kinetic_energy": series})
    write_csv(out / "bench.csv", COLUMNS, doc["rows"])
    write_csv(out / "scaling.csv", SCALING_COLUMNS, doc["scaling"])
    (out / "bench.json").write_text(json.dumps(doc, separators=(",", ":")))
    pngs = write_plots(doc, out)
    print_summary(doc, cfg, out, pngs, echo)
    return doc

