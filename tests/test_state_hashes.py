"""The state after a fixed number of steps is bit for bit the stored one (tests/state_hashes.py).

The shipped scenes with their own solver are checked by tests/test_scenes_smoke.py on the world
it steps anyway; this file runs the rest of QUICK (stack_20, friction_arch, mass_ratio_stacks
with the other solvers) and, under ``pytest --stress``, FULL (every scene with every solver).
"""

import pytest

from tests import state_hashes as sh


def pytest_generate_tests(metafunc):
    if "case" not in metafunc.fixturenames:
        return
    cases = [c for c in sh.quick_cases() if not c.own]
    if metafunc.config.getoption("--stress"):
        cases += sh.full_cases()
    metafunc.parametrize("case", cases, ids=[c.id for c in cases])


def test_state_hash(case):
    if not sh.comparable():
        pytest.skip("the stored bits are the CPU's; this session runs on another backend")
    stored = sh.stored()
    if stored is None:
        pytest.skip(sh.no_platform_message())
    expected = stored.get(case.id)
    if expected is None and case.steps == sh.FULL_STEPS:
        pytest.skip(f"no FULL hashes stored for this platform: `{sh.regenerate_hint(case)}` makes them")
    problem = sh.mismatch(case, expected, sh.run_case(case))
    assert problem is None, problem


def test_solver_list_is_the_registry():
    """The case lists spell the solvers out (collection imports no Taichi); they must be all of them."""
    from sandbox import SOLVERS

    assert list(sh.SOLVER_NAMES) == list(SOLVERS)
