"""Every shipped scene loads and runs 60 steps with its own solver settings, staying finite, and
ends bit for bit in the stored state (tests/state_hashes.py: the QUICK hash of its own-solver
case, checked here so that it costs no second world)."""

from pathlib import Path

import numpy as np
import pytest

from sandbox import Scene, World
from tests import state_hashes as sh
from tests.helpers import TEST_ARCH

SCENES = sorted((Path(__file__).resolve().parent.parent / "scenes").glob("*.toml"))


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_scene_runs_60_steps(path):
    world = World(Scene.load(path), arch=TEST_ARCH)
    world.step(60)
    st = world.state()
    for key, value in st.items():
        assert np.all(np.isfinite(value)), key
    m = world.metrics()
    assert np.isfinite(m["kinetic_energy"])
    # nothing fell through the floor: every body is above the lowest static geometry
    assert st["position"][:, 2].min() > -5.0
    stored = sh.stored()
    if stored is not None and sh.comparable():  # else tests/test_state_hashes.py skips, saying why
        case = sh.own_case(path)
        problem = sh.mismatch(case, stored.get(case.id), sh.hash_state(st))
        assert problem is None, problem
