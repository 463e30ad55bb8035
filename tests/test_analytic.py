"""Closed-form checks of the integrator and the contact model (house rule 9)."""

import dataclasses

import numpy as np
import pytest

from sandbox import Scene, World

from tests.helpers import TEST_ARCH, box_body, plane, scene_dict

G = 9.81
DT = 1.0 / 60.0


def test_free_fall_matches_symplectic_euler():
    """No contacts: x_{n+1} = x_n + h v_{n+1}, v_{n+1} = v_n + h g, reproduced in float32, with
    h = dt / iterations (each solver iteration is a substep of the step)."""
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 100.0], linear_velocity=[1.0, 0.0, 2.0])], statics=()))
    world = World(scene, solver="pgs", iterations=4, arch=TEST_ARCH)
    x = np.array([0, 0, 100.0], np.float32)
    v = np.array([1.0, 0.0, 2.0], np.float32)
    g = np.array([0, 0, -G], np.float32)
    iterations = 4
    h = np.float32(DT / iterations)
    for _ in range(120 * iterations):
        v = v + g * h
        x = x + h * v
    world.step(120)
    st = world.state()
    # the reference rounds each of its 480 substep updates to float32 (ulp 7.6e-6 m at 100 m; the
    # world keeps a remainder, bodies.py): ~sqrt(480) half-ulps, 8e-5 m
    np.testing.assert_allclose(st["position"][0], x, rtol=0, atol=1e-4)
    np.testing.assert_allclose(st["linear_velocity"][0], v, rtol=0, atol=1e-5)
    np.testing.assert_array_equal(st["orientation"][0], [1, 0, 0, 0])


def test_motion_below_float32_resolution_is_not_rounded_away():
    """1000 m from the origin a float32 step is 61 um; a body creeping at 10 um/s moves 11 nm
    per substep. Positions keep their rounding remainder (bodies.py), so after 10 s it is
    100 um further on, exactly, and a rebuild (adding a body) keeps that."""
    start = np.array([1000.0, 0.0, 0.0])
    speed = 1e-5
    body = box_body(start.tolist(), linear_velocity=[speed, 0.0, 0.0])
    world = World(Scene.from_dict(scene_dict([body], statics=(), gravity=(0.0, 0.0, 0.0))), solver="pgs",
                  iterations=15, arch=TEST_ARCH)
    world.step(600)
    moved = world.buf.bodies.exact_positions()[0] - start
    # each substep's update rounds at the remainder's own float32 step (at most half a step
    # of |x|, 61 um): 9000 such roundings bound the error, ~3e-8 m against the 61 um of before
    ulp = np.spacing(np.float32(1000.0))
    bound = 600 * 15 * np.spacing(np.float32(ulp / 2))
    np.testing.assert_allclose(moved, [speed * 10.0, 0.0, 0.0], rtol=0, atol=float(bound))
    assert world.state()["position"][0, 0] == np.float32(1000.0 + speed * 10.0)  # the nearest float32
    elsewhere = dataclasses.replace(world.body_specs[0], position=np.zeros(3))
    world.add_bodies([elsewhere])  # the rebuild re-uploads every body from the host
    np.testing.assert_array_equal(world.buf.bodies.exact_positions()[0] - start, moved)


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting", "block-mass-splitting", "pgs-colored"])
def test_resting_box_carries_weight_per_step(solver):
    """A settled box on a plane: total normal impulse = m g dt each step (rapier total_contact_impulse)."""
    mass = 1000.0
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 0.5])]))
    world = World(scene, solver=solver, iterations=20, arch=TEST_ARCH)
    world.track_impulses = True
    world.step(120)
    c = world.contacts()
    total = c["impulse"][:, 0].sum()
    assert len(c["impulse"]) == 4
    # relative 1e-3: float32 accumulation of ~1e2 N s per row over 20 iterations
    assert total == pytest.approx(mass * G * DT, rel=1e-3)
    st = world.state()
    assert np.abs(st["linear_velocity"]).max() < 1e-3


def _slope_scene(angle, mu):
    n = np.array([-np.sin(angle), 0.0, np.cos(angle)])
    # box resting on the slope, its bottom face on the plane
    q = [np.cos(angle / 2), 0.0, -np.sin(angle / 2), 0.0]
    pos = n * 0.5
    body = box_body(pos.tolist(), orientation=q, friction=mu)
    return Scene.from_dict(scene_dict([body], statics=[plane(normal=n.tolist(), friction=mu)]))


def _down_slope_displacement(world, angle, steps):
    x0 = world.state()["position"][0].copy()
    world.step(steps)
    d = world.state()["position"][0] - x0
    down = np.array([-np.cos(angle), 0.0, -np.sin(angle)])
    return float(d @ down)


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_box_sticks_below_friction_angle(solver):
    angle, mu = 0.25, 0.5  # tan(0.25) = 0.255 < 0.5
    world = World(_slope_scene(angle, mu), solver=solver, iterations=20, arch=TEST_ARCH)
    world.step(30)
    moved = _down_slope_displacement(world, angle, 120)
    assert abs(moved) < 1e-3  # [m] over 2 s: creep, not sliding


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_box_slides_above_friction_angle_with_coulomb_acceleration(solver):
    angle, mu = 0.4, 0.2  # tan(0.4) = 0.42 > 0.2
    world = World(_slope_scene(angle, mu), solver=solver, iterations=20, arch=TEST_ARCH)
    world.step(30)
    v0 = world.state()["linear_velocity"][0].copy()
    steps = 60
    world.step(steps)
    v1 = world.state()["linear_velocity"][0]
    down = np.array([-np.cos(angle), 0.0, -np.sin(angle)])
    accel = float((v1 - v0) @ down) / (steps * DT)
    expected = G * (np.sin(angle) - mu * np.cos(angle))
    assert accel == pytest.approx(expected, rel=0.02)  # method.md 2.16: within 2 % of analytic


def test_torque_free_spin_keeps_angular_momentum():
    """An asymmetric box spinning near its stable axis in zero gravity: |L| and L stay put."""
    body = box_body([0, 0, 0], half=(0.1, 0.3, 0.6), angular_velocity=[0.3, 0.2, 6.0])
    scene = Scene.from_dict(scene_dict([body], statics=(), gravity=(0, 0, 0)))
    world = World(scene, solver="pgs", iterations=4, arch=TEST_ARCH)

    def momentum():
        st = world.state()
        q = st["orientation"][0]
        w, x, y, z = q
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        inertia = scene.bodies[0].inertia
        return r @ inertia @ r.T @ st["angular_velocity"][0]

    l0 = momentum()
    world.step(600)
    l1 = momentum()
    # the implicit gyroscopic step dissipates slightly; 1 % over 10 s (method.md 2.13)
    assert np.linalg.norm(l1 - l0) / np.linalg.norm(l0) < 0.01
