"""``sandbox bench --quick``: its tables and plots have the promised shape, finite numbers and
the monotonicity that must hold. Its time budget is checked by benchmarks/bench_quick_budget.py
(a budget depends on the machine and on a warm kernel cache; a test does not assert one)."""

import csv
import importlib.util
import json
import math

import pytest

from sandbox import bench
from sandbox.cli import main
from tests.helpers import TEST_ARCH

TEXT_COLUMNS = {"scene", "engine", "solver", "options", "arch", "status"}
HAS_PYBULLET = importlib.util.find_spec("pybullet") is not None


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    pytest.importorskip("matplotlib")
    out = tmp_path_factory.mktemp("bench")
    rc = main(["bench", "--quick", "--quiet", "--arch", TEST_ARCH, "--out", str(out)])
    with open(out / "bench.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    with open(out / "scaling.csv", newline="") as fh:
        scaling = list(csv.DictReader(fh))

    def no_nan(token):
        raise AssertionError(f"bench.json holds {token}")

    doc = json.loads((out / "bench.json").read_text(), parse_constant=no_nan)
    return {"rc": rc, "out": out, "rows": rows, "scaling": scaling, "doc": doc}


def _sandbox_rows(rows, scene, solver):
    return sorted((r for r in rows if (r["scene"], r["engine"], r["solver"]) == (scene, "sandbox", solver)),
                  key=lambda r: int(r["iterations"]))


def test_quick_run_succeeds(quick):
    assert quick["rc"] == 0


def test_one_row_per_scene_solver_iteration(quick):
    q = bench.QUICK
    expected = {(s, "sandbox", v, str(k)) for s in q["scenes"] for v in q["solvers"] for k in q["iterations"]}
    if HAS_PYBULLET:
        expected |= {(s, "pybullet", "pybullet", str(k)) for s in q["scenes"] for k in q["iterations"]}
    got = [(r["scene"], r["engine"], r["solver"], r["iterations"]) for r in quick["rows"]]
    assert len(got) == len(set(got)) and set(got) == expected
    assert len(quick["doc"]["rows"]) == len(quick["rows"])
    assert list(quick["rows"][0]) == list(bench.COLUMNS) == quick["doc"]["columns"]
    assert all(r["status"] == "ok" for r in quick["rows"])


def test_every_number_is_finite(quick):
    for r in quick["rows"]:
        for col, cell in r.items():
            if col in TEXT_COLUMNS:
                continue
            allowed_empty = (r["engine"] == "pybullet" and col in bench.NOT_MEASURED_FOR_PYBULLET) or (
                not HAS_PYBULLET and col.endswith("_to_pybullet"))
            if cell == "":
                assert allowed_empty, f"{r['scene']} {r['solver']} x{r['iterations']}: {col} is empty"
                continue
            assert math.isfinite(float(cell)), f"{r['scene']} {r['solver']} x{r['iterations']}: {col} = {cell}"
    for r in quick["scaling"]:
        assert r["status"] == "ok"
        for col in ("bodies", "contacts", "ms_per_step", "steps_per_s", "kinetic_energy"):
            assert math.isfinite(float(r[col]))


def test_numbers_are_sane(quick):
    for r in quick["rows"]:
        ms, rate = float(r["ms_per_step"]), float(r["steps_per_s"])
        assert ms > 0 and rate > 0
        assert int(r["bodies"]) == 210 and int(r["contacts"]) > 0
        for col in ("kinetic_energy", "max_penetration", "mean_penetration", "drift"):
            assert float(r[col]) >= 0.0
        assert float(r["mean_penetration"]) <= float(r["max_penetration"])
        if r["engine"] == "sandbox":
            assert float(r["residual_rms"]) <= float(r["residual_max"]) + 1e-12


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_frozen_residual_falls_with_iterations(quick, solver):
    """On one frozen step of the settled pyramid, more sweeps of pgs or mass splitting give a
    smaller residual (both converge on this problem; the closed-loop numbers need not)."""
    rows = _sandbox_rows(quick["rows"], "pyramid_20", solver)
    residual = [float(r["frozen_residual"]) for r in rows]
    assert len(residual) == len(bench.QUICK["iterations"]) >= 3
    assert all(a > b for a, b in zip(residual, residual[1:])), residual
    curve = next(c for c in quick["doc"]["convergence"]["pyramid_20"] if c["solver"] == solver)
    assert curve["status"] == "ok" and len(curve["residual"]) == max(bench.QUICK["iterations"])
    assert curve["residual"][-1] < curve["residual"][0]
    assert curve["ms_per_sweep"] > 0


def test_plots_exist(quick):
    names = [f"{kind}_{s}.png" for s in bench.QUICK["scenes"] for kind in ("pareto", "jitter", "convergence")]
    for name in names + ["scaling.png"]:
        data = (quick["out"] / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, name


def test_scaling_covers_the_sizes(quick):
    q = bench.QUICK
    engines = len(q["solvers"]) + (1 if HAS_PYBULLET else 0)
    assert len(quick["scaling"]) == len(q["scaling_sizes"]) * engines
    bodies = sorted({int(r["bodies"]) for r in quick["scaling"]})
    assert len(bodies) == len(q["scaling_sizes"]) and bodies[0] >= q["scaling_sizes"][0]


@pytest.mark.skipif(not HAS_PYBULLET, reason="pybullet is not importable")
def test_pybullet_side_by_side(quick):
    pb = [r for r in quick["rows"] if r["engine"] == "pybullet"]
    assert sorted(int(r["iterations"]) for r in pb) == sorted(bench.QUICK["iterations"])
    assert quick["doc"]["meta"]["pybullet"]
    for r in quick["rows"]:
        if r["engine"] == "sandbox":
            assert float(r["steps_per_s_ratio_to_pybullet"]) > 0
            assert float(r["kinetic_energy_ratio_to_pybullet"]) >= 0
    assert any(r["engine"] == "pybullet" for r in quick["scaling"])
