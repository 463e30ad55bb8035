"""The CPU team's position update eight bodies at a time (sandbox/pose_lanes.py) against the
body-by-body one (integrate.advance_pose) that every other launch runs: the same bits, with
damping, static bodies and a last group that is not full, while the bodies land, spin and rest."""

import numpy as np
import pytest

from sandbox import Scene, Settings, World

from tests.helpers import TEST_ARCH, assert_same_state, box_body, scene_dict


def _tumbling_boxes() -> dict:
    """43 boxes of unequal sides (an anisotropic inertia: the gyroscopic solve), every third one
    damped, spun about a skew axis and dropped in rows onto a static slab, 43 = 5 groups of eight and
    three."""
    rng = np.random.default_rng(3)
    bodies = [box_body([0.0, 0.0, -0.25], half=(6.0, 6.0, 0.25), static=True)]
    for k in range(43):
        x, y, z = (k % 5) * 1.4 - 2.8, ((k // 5) % 3) * 1.4 - 1.4, 1.0 + (k // 15) * 1.4
        extra = {"linear_damping": 0.5, "angular_damping": 2.0} if k % 3 == 0 else {}
        bodies.append(box_body([x, y, z], half=tuple(rng.uniform(0.15, 0.5, 3)),
                               angular_velocity=list(rng.uniform(-6.0, 6.0, 3)), **extra))
    return scene_dict(bodies, statics=())


@pytest.mark.parametrize("solver", ["mass-splitting", "pgs-colored"])
def test_the_team_moves_the_bodies_eight_at_a_time_to_the_same_bits(solver):
    scene = Scene.from_dict(_tumbling_boxes())
    states = {}
    for launch in ("shared", "one" if solver != "pgs-colored" else "per-stage"):
        world = World(scene, solver=solver, iterations=6, arch=TEST_ARCH, settings=Settings(iteration_launch=launch))
        assert world.compiled_effects.gyroscopic and world.compiled_effects.damping
        world.step(45)
        states[launch] = world.state()
        assert world.metrics()["contacts"] > 40  # they have landed
    first, second = states.values()
    assert np.abs(first["angular_velocity"]).max() > 0.1  # still turning: the solve has work to do
    assert_same_state(first, second)
