"""A look inside one solve (sandbox/inspection.py): a step run sweep by sweep ends in the state
``World.step`` reaches, and what a pause shows is consistent with it."""

import numpy as np
import pytest

from sandbox import SandboxError, Scene, World
from sandbox.scene.library import SCENES_DIR
from tests.helpers import TEST_ARCH


def _world(solver: str, **kwargs) -> World:
    world = World(Scene.load(SCENES_DIR / "stack_20.toml"), solver=solver, iterations=4, arch=TEST_ARCH, **kwargs)
    world.step(30)  # warm-started, resting
    return world


@pytest.mark.parametrize("solver, formulation", [("pgs", "soft-step"), ("mass-splitting", "soft-step"),
                                                 ("block-mass-splitting", "paper")])
def test_a_step_run_sweep_by_sweep_is_bitwise_a_step(solver, formulation):
    plain, inspected = _world(solver, formulation=formulation), _world(solver, formulation=formulation)
    plain.step(1)
    inspection = inspected.inspect_step()
    sweeps = []
    while (sweep := inspection.advance()) is not None:
        sweeps.append((sweep.substep, sweep.phase))
        inspection.contacts()  # reading between sweeps changes nothing
    # a substep's sweeps: at 4 iterations every schedule sweeps twice of each kind
    # (Settings.step_sweeps); the paper's one step sweeps 4 times and never relaxes
    twice = ["biased", "biased", "relax", "relax"]
    per_substep = {"pgs": twice, "mass-splitting": twice, "block-mass-splitting": ["biased"] * 4}[solver]
    substeps = 4 if formulation == "soft-step" else 1
    assert sweeps == [(i, phase) for i in range(substeps) for phase in per_substep]
    assert len(sweeps) == len(inspection.residuals)
    a, b = plain.state(), inspected.state()
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    assert inspected.step_count == plain.step_count
    inspected.step(1)  # the world steps on normally afterwards


def test_sub_bodies_average_to_the_merged_velocity_and_pgs_has_none():
    """The paper's plain average (relaxation 1): a resting column box's merged velocity is the
    mean of its sub-bodies', one per contact point touching it."""
    world = _world("mass-splitting", relaxation=1.0)
    inspection = world.inspect_step()
    sweep = inspection.advance()
    assert sweep.phase == "biased" and not sweep.carries_warm_start
    with pytest.raises(SandboxError, match="finish it first"):
        world.step(1)
    sub = inspection.sub_bodies(10)  # a box in the middle of the column: one block per corner above and below
    assert len(sub["linear"]) == len(sub["blocks"]) >= 4
    assert sub["split"] == len(sub["blocks"])  # every point touching the box acts
    assert np.allclose(sub["merged"][0], sub["linear"].mean(axis=0), atol=1e-6)
    assert np.allclose(sub["merged"][1], sub["angular"].mean(axis=0), atol=1e-6)
    assert np.ptp(sub["linear"][:, 2]) > 1e-4  # the sub-bodies did differ: each block moved its own
    contacts = inspection.contacts()
    assert contacts["impulse"].min() >= 0.0 and np.all(np.isfinite(contacts["residual"]))
    inspection.finish()
    assert inspection.advance() is None
    with pytest.raises(SandboxError, match="not paused"):
        inspection.contacts()
    pgs = _world("pgs").inspect_step()
    pgs.advance()
    assert pgs.sub_bodies(10) is None
