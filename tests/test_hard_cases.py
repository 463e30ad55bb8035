"""Hard cases stay numerically stable (method.md section 2; cases in sandbox/hard_cases.py).

CI runs serial PGS and mass splitting at 4 and 15 iterations; ``pytest --stress`` runs every
solver at 4 and 15 iterations (the same grid as docs/stability.md). A case a solver is known to fail
is marked xfail(strict) with the measured figures, so the failure stays visible and a fix
shows up as an unexpected pass that forces this table to be updated.
"""

import pytest

from sandbox import SOLVERS
from sandbox.hard_cases import all_cases, run_case
from tests.helpers import TEST_ARCH

CASES = {case.name: case for case in all_cases()}

KNOWN_FAILURES = {
    # Figures measured 2026-11-25 (docs/stability.md, benchmarks/stability_matrix.py) on the 2-core
    # CPU machine, with the preload (solvers/contact_spring.py): it turned 23 cells of the matrix
    # from FAIL to PASS (1:100 at 4 iterations, 1:1000 and the 1 mm cubes at 15, the 20-box stack
    # at 4 with mass splitting) and none the other way.
    # since 2026-11-27 the Jacobi family sweeps a light body's blocks twice more per substep (Settings.ratio_sweeps):
    # mass splitting and Jacobi hold the column from 8 iterations (61.5 mm before), block mass splitting from 15
    # since 2026-11-28 every schedule runs two sweeps of each kind per substep at 4 iterations
    # (Settings.step_sweeps; first the Jacobi family, then the PGS solvers); the figures before it are in brackets
    ("heavy_on_light_1to1000", "*@4"): "at 4 iterations the PGS family and block mass splitting tip the column "
                                       "(3.7-5.0 m; PGS 3.7-4.4 m), mass splitting and Jacobi let the 1000 kg top "
                                       "sink 45.6 mm (54.0 mm before the light rows' own damping ratio, 80-89 mm before "
                                       "their six extra sweeps, 159-169 mm)",
    ("stack_3_of_0.001m", "*@4"): "at 4 iterations the 1 mm cubes sink 0.98 mm under mass splitting and Jacobi (a "
                                  "pair ends coincident), the PGS family's top drifts 3.5 mm sideways, block mass "
                                  "splitting's 2.8 mm, 0.79 mm deep (criteria: drift 2 %, penetration 5 % of the size)",
    ("stack_3_of_0.001m", "block-mass-splitting@15"): "the top 1 mm cube drifts 0.027 mm at 15 iterations "
                                                      "(criterion 0.02 mm)",
    ("deep_overlap_30pct", "mass-splitting@4"): "10.5 mm still overlapping after 3 s at 4 iterations (criterion "
                                                "10 mm; 21.6 mm)",
    ("friction_arch", "jacobi@4"): "a voussoir slips 35.2 mm at 4 iterations (the arch collapsed, peak 13 m/s)",
    # projected Jacobi takes its busiest body's split as its one global factor since 2026-11-26
    # (block_adjacency.MODE_JACOBI_BOUNDED): the card house stands from 15 iterations instead of flying
    # apart at every count, and the 27-box block and the overlapping boxes, whose busiest bodies touch at
    # 68 and 24 points, step as softly as that body everywhere
    ("leaning_planks", "jacobi@4"): "a plank slides 16.6 mm at 4 iterations (the card house collapsed, 0.5 m)",
    ("deep_overlap_30pct", "jacobi@4"): "11.7 mm still overlapping after 3 s at 4 iterations (29 mm)",
    ("leaning_planks", "mass-splitting@4"): "the card house collapses at 4 iterations (a card moves 1.6 m)",
    # the plain stack stands at 4 iterations with mass splitting and Jacobi only because their sweeps keep a
    # straight column straight: nudged, it buckles (P-Delta on springs the stability limit keeps soft,
    # docs/method-notes.md). Since 2026-11-27 a face resists rocking more stiffly than its capped spring
    # (Settings.contact_rocking_stiffness): serial and coloured PGS hold it at 4 (8.0 / 2.9 mm; serial PGS's
    # plain column, which leaned over after ~700 steps, 7.1 mm), mass splitting and Jacobi from 8; block mass
    # splitting, left out of it, from 8 as before
    # (2026-11-28: run on to 30 s, benchmarks/stability_matrix.py WATCH, each of these four columns falls,
    # its top reaching 22-24 m/s: the lean slowed, it did not stop)
    ("nudged_stack_20", "jacobi@4"): "the nudged column leans at 4 iterations (top 33.4 mm in 10 s; 153.6 mm) "
                                     "and falls within 30 s",
    ("nudged_stack_20", "mass-splitting@4"): "the nudged column leans at 4 iterations (top 37.6 mm in 10 s; "
                                             "150.3 mm) and falls within 30 s",
    ("nudged_stack_20", "block-mass-splitting@4"): "the nudged column buckles at 4 iterations (top 137.3 mm in 10 s; "
                                                   "668.3 mm) and falls within 30 s",
    ("stack_20", "block-mass-splitting@4"): "the column leans at 4 iterations (top 176.3 mm in 10 s; 811.7 mm) and "
                                            "falls within 30 s",
    # serial PGS's card house, which collapsed at 4 iterations since its visiting order turns every substep
    # (2026-11-26), stands since the PGS solvers sweep twice of each kind per substep there too (0.21 mm)
    # the 1:1000 column struck down by 0.3 m/s after it settled (2026-11-28, docs/method-notes.md "A kicked
    # column keeps bouncing"): at 15 iterations serial and coloured PGS still it within a second, and every
    # split schedule since its light rows take the limit of the sweeps they get, six extra ("A kicked column:
    # light rows stiffer than their sweeps")
    # since the light rows' own damping ratio (Settings.light_damping_ratio, "A struck column at 8 iterations")
    # mass splitting and Jacobi bring it back to rest at 8 too, and at 4 it comes to rest, too deep
    ("kicked_heavy_on_light_1to1000", "*@4"): "at 4 iterations the column is down before the kick (the PGS family "
                                              "and block mass splitting tip it, 3.7-5.0 m) or comes to rest 28.8 mm "
                                              "deep after it (mass splitting, Jacobi: 2e-6 J in the last second; "
                                              "231 mm and still astir, 0.58 J, before the light rows' damping)",
}


def _known(case: str, solver: str, iterations: int):
    for key in ((case, "*"), (case, f"*@{iterations}"), (case, solver), (case, f"{solver}@{iterations}")):
        if key in KNOWN_FAILURES:
            return KNOWN_FAILURES[key]
    return None


def pytest_generate_tests(metafunc):
    if "combo" not in metafunc.fixturenames:
        return
    stress = metafunc.config.getoption("--stress")
    solvers = list(SOLVERS) if stress else ["pgs", "mass-splitting"]
    iterations = [4, 15]
    params = []
    for name in CASES:
        for solver in solvers:
            for k in iterations:
                reason = _known(name, solver, k)
                marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
                params.append(pytest.param((name, solver, k), marks=marks, id=f"{name}-{solver}-{k}"))
    metafunc.parametrize("combo", params)


def test_hard_case(combo):
    name, solver, iterations = combo
    r = run_case(CASES[name], solver, iterations, arch=TEST_ARCH)
    assert r.passed, f"{name} with {solver} at {iterations} iterations: {r.figures}"


ROUNDING_AT_500 = ("at 500 substeps (h = 33 us) a position update is ~1e-8 m, below float32 resolution at 1 m: "
                   "rounding keeps the block stirring (mean KE of the last second 1.9e-2 J with pgs, 7.2e-2 J with "
                   "mass splitting, criterion 1e-2 J)")


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_resting_block_at_one_iteration_stays_finite(request, solver):
    if not request.config.getoption("--stress"):
        pytest.skip("stress only (pytest --stress)")
    r = run_case(CASES["resting_block_27"], solver, 1, arch=TEST_ARCH)
    assert "non-finite" not in r.figures and "stopped" not in r.figures, r.figures


@pytest.mark.parametrize("solver", [pytest.param(s, marks=pytest.mark.xfail(strict=True, reason=ROUNDING_AT_500))
                                    for s in ("pgs", "mass-splitting")])
def test_resting_block_at_500_iterations_is_at_rest(request, solver):
    if not request.config.getoption("--stress"):
        pytest.skip("stress only (pytest --stress): 500 substeps per step")
    r = run_case(CASES["resting_block_27"], solver, 500, arch=TEST_ARCH)
    assert r.passed, r.figures


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_long_run_of_a_resting_block(request, solver):
    """10 000 steps (2 min 47 s simulated) of the resting block: finite and still at rest."""
    if not request.config.getoption("--stress"):
        pytest.skip("stress only (pytest --stress): 10 000 steps")
    r = run_case(CASES["resting_block_27"], solver, 15, steps=10_000, arch=TEST_ARCH)
    assert r.passed, r.figures


def test_watching_past_the_window_leaves_the_verdict_alone():
    """run_case's ``watch`` (the stability matrix's WATCH): the world runs on for the peak speed and
    the energy gain, while the judge reads the case's own window, so no criterion moves."""
    case = CASES["nudged_stack_20"]
    window = run_case(case, "mass-splitting", 4, steps=40, arch=TEST_ARCH)
    watched = run_case(case, "mass-splitting", 4, steps=40, arch=TEST_ARCH, watch=3)
    assert (watched.passed, watched.figures) == (window.passed, window.figures)
    assert watched.peak_speed >= window.peak_speed and watched.energy_gain >= window.energy_gain
