"""A step that produces non-finite numbers stops with a message and keeps the last good state."""

import numpy as np
import pytest

from sandbox import Scene, Settings, SimulationError, World

from tests.helpers import TEST_ARCH, box_body, scene_dict


def _failing_step_keeps_state(world) -> str:
    """Step once, expecting a SimulationError; the state must be the one before. Returns the message."""
    before = world.state()
    with pytest.raises(SimulationError) as err:
        world.step(1)
    after = world.state()
    for key in before:
        np.testing.assert_array_equal(before[key], after[key], err_msg=key)
    return str(err.value)


def test_diverging_step_names_stage_and_body_and_keeps_last_good_state():
    # two stacked tall boxes under plain Jacobi (relaxation 1) blow up within one step
    tall = (0.2, 0.2, 1.0)
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 1.0], half=tall), box_body([0, 0, 3.0], half=tall)]))
    world = World(scene, solver="jacobi", iterations=1, arch=TEST_ARCH, relaxation=1.0,
                  settings=Settings(warm_start=0.0, sweeps=400))
    text = _failing_step_keeps_state(world)
    assert "non-finite" in text and "body" in text and "last good state" in text
    # the world is still usable: switch to a convergent solver and go on
    world.set_solver("mass-splitting", iterations=10)
    world.settings = Settings()
    world.step(30)
    assert np.all(np.isfinite(world.state()["position"]))


def test_runaway_body_stops_the_step_before_the_broadphase_overflows():
    """A finite but absurd speed (a diverged solver) would make the body's swept bounds cover
    billions of grid cells; the step stops with a message instead of overflowing or hanging."""
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 0.5]), box_body([3, 0, 0.5])]))
    world = World(scene, solver="pgs", iterations=4, arch=TEST_ARCH)
    world.step(2)
    world.set_velocity([1], angular=[0.0, 0.0, 3e7])
    text = _failing_step_keeps_state(world)
    assert "body 1" in text and "broadphase cells" in text and "last good state" in text
    world.set_velocity([1], angular=[0.0, 0.0, 0.0])
    world.step(5)  # and the world goes on
    assert np.all(np.isfinite(world.state()["position"]))


def test_a_pose_that_turns_non_finite_is_named_and_the_step_undone():
    """A finite spin so fast that the rotation step overflows float32 (|w| h / 2 > 1.8e19) turns
    the orientation into NaN while every velocity stays finite: the once-per-step check at the
    step's end (integrate.check_bodies_loops) names the pose, and the world keeps its last good
    state."""
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 5.0]), box_body([3, 0, 0.5])]))
    world = World(scene, solver="mass-splitting", iterations=4, arch=TEST_ARCH)
    world.step(2)
    world.set_velocity([0], angular=[0.0, 0.0, 1e30])
    text = _failing_step_keeps_state(world)
    assert "non-finite integrate_positions (pose) of body 0" in text and "last good state" in text


def test_colored_pgs_with_restitution_steps_on_the_cpu():
    """The restitution pass sweeps colour by colour even when the iterations run in one launch:
    it reads the colour ranges itself (a bouncing box, pgs-colored, CPU)."""
    bouncy = box_body([0, 0, 1.5], restitution=0.5)
    scene = Scene.from_dict(scene_dict([bouncy], solver="pgs-colored", iterations=8))
    world = World(scene, arch=TEST_ARCH)
    world.step(60)
    z = world.state()["position"][0, 2]
    assert np.isfinite(z) and 0.45 < z < 1.6


def test_a_failed_step_keeps_the_support_loads_of_the_last_good_state():
    """The support loads (solvers/contact_spring.py) are state too: the step's end updates them from
    its impulses, so a diverged step must not leave its loads behind for the next one's springs."""
    tall = (0.2, 0.2, 1.0)
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 1.0], half=tall), box_body([0, 0, 3.0], half=tall)]))
    world = World(scene, solver="mass-splitting", iterations=10, arch=TEST_ARCH)
    world.step(30)
    bodies = world.buf.bodies
    loads = bodies.read_loads(2)
    assert loads["support"].min() > 0.0  # the column has learnt its loads
    world.set_solver("jacobi", iterations=1, relaxation=1.0)
    world.settings = Settings(warm_start=0.0, sweeps=400)  # diverges within the step (the test above)
    _failing_step_keeps_state(world)
    for name, before in loads.items():
        np.testing.assert_array_equal(before, bodies.read_loads(2)[name], err_msg=name)
