"""Motion resistances and speculative contacts as effects (issue 16): rolling and torsional
friction, linear and angular damping, each compiled in only where a body has it, and
speculative contacts switched by the world's settings. Each is checked against the motion it
must produce, for every solver where the solver takes part."""

import numpy as np
import pytest

from sandbox import SOLVERS, Scene, World
from tests.helpers import G, TEST_ARCH, box_body, plane, scene_dict, sphere_body

RADIUS = 0.5
DT = 1.0 / 60.0


def _world(bodies, statics=(plane(),), gravity=(0.0, 0.0, -G), solver="pgs", world=None):
    d = scene_dict(bodies, statics=statics, gravity=gravity, solver=solver)
    d["world"].update(world or {})
    return World(Scene.from_dict(d), arch=TEST_ARCH)


def _rolling_sphere(**extra) -> dict:
    """A solid sphere rolling without slipping along x at 2 m/s on the ground plane."""
    return sphere_body([0.0, 0.0, RADIUS], radius=RADIUS, linear_velocity=[2.0, 0.0, 0.0],
                       angular_velocity=[0.0, 2.0 / RADIUS, 0.0], **extra)


@pytest.mark.parametrize("solver", SOLVERS)
def test_rolling_friction_slows_a_rolling_sphere_at_the_rate_its_lever_arm_gives(solver):
    """A rolling-resistance torque mu_r N on a solid sphere decelerates it by
    mu_r g / (r (1 + 2/5)), and it keeps rolling without slipping."""
    mu_r = 0.02
    world = _world([_rolling_sphere(rolling_friction=mu_r)], solver=solver)
    assert world.compiled_effects.rolling_friction
    world.step(60)
    state = world.state()
    v, w = state["linear_velocity"][0], state["angular_velocity"][0]
    drop = 2.0 - v[0]
    expected = mu_r * G / (RADIUS * 1.4) * 60 * DT
    assert abs(drop - expected) < 0.01 * expected, (drop, expected)
    assert abs(v[0] - w[1] * RADIUS) < 1e-2  # still rolling, not sliding


def test_without_rolling_friction_a_sphere_rolls_on_and_the_rows_are_not_compiled():
    world = _world([_rolling_sphere()])
    assert not world.compiled_effects.rolling_friction
    world.step(60)
    assert abs(world.state()["linear_velocity"][0][0] - 2.0) < 2e-3


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_torsional_friction_stops_a_spinning_sphere_at_the_rate_its_lever_arm_gives(solver):
    """Spinning about the contact normal, a torque mu_t N on a solid sphere (I = 2/5 m r^2)
    slows it by mu_t g / (2/5 r^2); it then stays stopped, never turned back."""
    mu_t, w0 = 0.05, 6.0
    world = _world([sphere_body([0.0, 0.0, RADIUS], radius=RADIUS, angular_velocity=[0.0, 0.0, w0],
                                torsional_friction=mu_t)], solver=solver)
    world.step(30)
    wz = world.state()["angular_velocity"][0][2]
    expected = mu_t * G / (0.4 * RADIUS**2) * 30 * DT
    assert abs((w0 - wz) - expected) < 0.01 * expected, (w0 - wz, expected)
    world.step(60)
    assert abs(world.state()["angular_velocity"][0][2]) < 1e-3


def test_damping_slows_a_free_body_by_the_implicit_factor_each_substep():
    """v' = v / (1 + h c) every substep h = dt / iterations: after n substeps v0 / (1 + h c)^n,
    linear and angular alike; a body without damping in the same world keeps its speed."""
    lin, ang = 0.5, 2.0
    v0, w0 = np.array([3.0, 0.0, 0.0]), np.array([0.0, 0.0, 2.0])
    world = _world([sphere_body([0.0, 0.0, 0.0], linear_velocity=v0.tolist(), angular_velocity=w0.tolist(),
                                linear_damping=lin, angular_damping=ang),
                    sphere_body([0.0, 5.0, 0.0], linear_velocity=v0.tolist())],
                   statics=(), gravity=(0.0, 0.0, 0.0))
    assert world.compiled_effects.damping
    world.step(60)
    state = world.state()
    n = 60 * world.iterations
    h = DT / world.iterations
    np.testing.assert_allclose(state["linear_velocity"][0], v0 / (1.0 + h * lin) ** n, rtol=2e-4, atol=1e-7)
    np.testing.assert_allclose(state["angular_velocity"][0], w0 / (1.0 + h * ang) ** n, rtol=2e-4, atol=1e-7)
    np.testing.assert_array_equal(state["linear_velocity"][1], v0.astype(np.float32))


def test_heavy_damping_stops_a_body_without_turning_it_back():
    world = _world([box_body([0.0, 0.0, 0.0], linear_velocity=[5.0, 0.0, 0.0], angular_velocity=[0.0, 3.0, 0.0],
                             linear_damping=1e6, angular_damping=1e6)], statics=(), gravity=(0.0, 0.0, 0.0))
    world.step(10)
    state = world.state()
    assert 0.0 <= state["linear_velocity"][0][0] < 1e-3 and 0.0 <= state["angular_velocity"][0][1] < 1e-3
    assert 0.0 < state["position"][0][0] < 5.0 * DT  # it moved a little, forwards only


def _bullet_world(**world):
    """A 5 cm sphere at 60 m/s (1 m per step) towards a 10 cm wall 1.45 m away, no gravity."""
    wall = {"shape": "box", "half_extents": [0.05, 1.0, 1.0], "position": [1.5, 0.0, 0.0]}
    bullet = sphere_body([0.0, 0.0, 0.0], radius=0.05, linear_velocity=[60.0, 0.0, 0.0])
    return _world([bullet], statics=(wall,), gravity=(0.0, 0.0, 0.0), world=world)


@pytest.mark.parametrize("world_keys, stops", [
    ({}, True),  # speculative contacts on (the default): caught in the step before it would pass
    ({"speculative_contacts": False}, False),  # off: 1 m per step jumps the wall
    ({"speculative_speed": 100.0}, False),  # on, but only for bodies faster than 100 m/s
    ({"speculative_speed": 10.0}, True),
])
def test_speculative_contacts_catch_a_fast_body_only_when_on_and_it_is_fast_enough(world_keys, stops):
    world = _bullet_world(**world_keys)
    assert world.compiled_effects.speculative == world_keys.get("speculative_contacts", True)
    world.step(4)
    x = world.state()["position"][0][0]
    if stops:
        assert x < 1.45 - 0.05 + 1e-3, x  # in front of the wall
    else:
        assert x > 1.55 + 0.05, x  # through it
