"""Effects compiled in on demand (issue 16): the switches a world's kernels are built with
follow what its scene asks for and what its bodies can use, and an absent effect changes the
motion only where it would have acted."""

import numpy as np
import pytest

from sandbox import SandboxError, Scene, Settings, World
from sandbox.scene.library import resolve_scene
from sandbox.solvers.schedule import Schedule
from sandbox.scene.rotations import quat_to_matrix
from tests.helpers import TEST_ARCH, box_body, plane, scene_dict, sphere_body


def _world(bodies, effects=("friction", "restitution"), statics=None, gravity=(0.0, 0.0, -9.81)):
    d = scene_dict(bodies, statics=statics if statics is not None else (plane(),), gravity=gravity)
    d["effects"] = list(effects)
    return World(Scene.from_dict(d), arch=TEST_ARCH)


def test_frictionless_spheres_compile_neither_friction_rows_nor_the_gyroscopic_step():
    spheres = [sphere_body([0.0, 0.0, 0.5 + 1.1 * k], friction=0.0) for k in range(3)]
    world = _world(spheres, statics=(plane(friction=0.0),))
    compiled = world.compiled_effects
    assert not compiled.friction and not compiled.gyroscopic
    assert compiled.restitution is False  # every restitution is 0: the bounce pass compiles away too
    world.step(30)
    assert world.metrics()["contacts"] > 0  # the spheres do touch: only the friction rows are absent


def test_an_effect_is_compiled_in_where_a_body_uses_it():
    cubes = [box_body([0.0, 0.0, 0.5])]
    assert _world(cubes).compiled_effects.as_dict() == {"friction": True, "restitution": False,
                                                        "gyroscopic": False, "sleeping": False, "damping": False,
                                                        "rolling_friction": False, "speculative": True,
                                                        "light_bodies": False}
    plank = [box_body([0.0, 0.0, 0.5], half=(1.0, 0.25, 0.1))]  # anisotropic inertia
    assert _world(plank).compiled_effects.gyroscopic
    bouncy = [box_body([0.0, 0.0, 0.5], restitution=0.5)]
    assert _world(bouncy, effects=("restitution", "sleeping")).compiled_effects.as_dict() == {
        "friction": False, "restitution": True, "gyroscopic": False, "sleeping": True, "damping": False,
        "rolling_friction": False, "speculative": True, "light_bodies": False}


def test_adding_a_body_recompiles_for_what_it_needs():
    """A plank dropped into a world of cubes turns the gyroscopic step on; removing it turns it off."""
    world = _world([box_body([0.0, 0.0, 0.5])])
    assert not world.compiled_effects.gyroscopic
    plank = Scene.from_dict(scene_dict([box_body([3.0, 0.0, 0.5], half=(1.0, 0.25, 0.1))])).bodies[0]
    world.add_bodies([plank])
    assert world.compiled_effects.gyroscopic
    world.remove_bodies([1])
    assert not world.compiled_effects.gyroscopic


def test_reserved_kinds_compile_what_a_later_plank_needs_from_the_start():
    """The web sandbox's worlds (reserve_kinds): the gyroscopic step is in before the plank comes,
    so its arrival compiles nothing; spheres alone reserve nothing of it; an unknown kind is refused."""
    world = World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5])])), arch=TEST_ARCH,
                  reserve_kinds=("box", "hull"))
    before = world.compiled_effects
    assert before.gyroscopic
    plank = Scene.from_dict(scene_dict([box_body([3.0, 0.0, 0.5], half=(1.0, 0.25, 0.1))])).bodies[0]
    world.prepare_edits()
    world.add_bodies([plank])
    assert world.compiled_effects == before
    spheres = World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5])])), arch=TEST_ARCH, reserve_kinds=("sphere",))
    assert not spheres.compiled_effects.gyroscopic
    with pytest.raises(SandboxError, match="unknown shape kind"):
        World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5])])), arch=TEST_ARCH, reserve_kinds=("cone",))


def test_the_light_bodies_sweeps_compile_in_where_masses_differ_enough():
    """The Jacobi family's extra sweeps over light bodies' blocks (light_bodies.py) are compiled in
    while some dynamic body is ``ratio_mass`` times lighter than another, or may become so (a
    scene's drops, reserved kinds); without them a step plans no extra sweep (on a GPU, five
    launches fewer per substep)."""
    world = World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5 + i]) for i in range(2)])),
                  solver="mass-splitting", iterations=4, arch=TEST_ARCH)
    assert not world.compiled_effects.light_bodies
    schedule = Schedule("mass-splitting", {})
    assert schedule.plan(world.settings, 4, world.compiled_effects.light_bodies).ratio == 0
    heavy = Scene.from_dict(scene_dict([box_body([3.0, 0.0, 0.5], mass=5000.0)])).bodies[0]  # 5x a 1000 kg cube
    world.add_bodies([heavy])
    assert world.compiled_effects.light_bodies
    assert schedule.plan(world.settings, 4, world.compiled_effects.light_bodies).ratio == Settings().ratio_sweeps
    world.remove_bodies([2])
    assert not world.compiled_effects.light_bodies
    spread = [box_body([0.0, 0.0, 0.5]), box_body([3.0, 0.0, 0.5], mass=4000.0)]  # 4-fold: below ratio_mass
    assert not _world(spread).compiled_effects.light_bodies
    four = World(Scene.from_dict(scene_dict(spread)), arch=TEST_ARCH, settings=Settings(ratio_mass=4.0))
    assert four.compiled_effects.light_bodies
    off = World(Scene.from_dict(scene_dict(spread)), arch=TEST_ARCH, settings=Settings(ratio_mass=4.0, ratio_sweeps=0))
    assert not off.compiled_effects.light_bodies
    reserved = World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5])])), arch=TEST_ARCH, reserve_kinds=("box",))
    assert reserved.compiled_effects.light_bodies
    drops = Scene.load(resolve_scene("scripted_drop_300"))  # equal boxes now, heavier ones dropped later
    assert len({b.mass for b in drops.bodies if not b.static}) == 1
    assert World(drops, arch=TEST_ARCH).compiled_effects.light_bodies


def test_cubes_and_spheres_turn_freely_without_the_gyroscopic_step():
    """Isotropic bodies in free flight keep their angular velocity exactly and turn by the
    Cayley step about it, as the full midpoint solve would (to float32 rounding)."""
    w0 = np.array([1.0, 2.0, -3.0])
    bodies = [box_body([0.0, 0.0, 0.0], angular_velocity=w0.tolist()),
              sphere_body([3.0, 0.0, 0.0], angular_velocity=w0.tolist())]
    world = _world(bodies, statics=(), gravity=(0.0, 0.0, 0.0))
    assert not world.compiled_effects.gyroscopic
    world.step(60)
    state = world.state()
    assert np.array_equal(state["angular_velocity"], np.tile(w0.astype(np.float32), (2, 1)))
    # after 1 s at |w| = sqrt(14) rad/s about a fixed axis: the rotation angle, from the quaternion
    q = state["orientation"][0].astype(np.float64)
    angle = 2.0 * np.arctan2(np.linalg.norm(q[1:]), q[0])
    assert angle == pytest.approx(np.sqrt(14.0), abs=2e-3)  # Cayley's angle error is O(h^2)
    assert np.allclose(q[1:] / np.linalg.norm(q[1:]), w0 / np.linalg.norm(w0), atol=1e-5)


def test_a_plank_still_tumbles_by_the_gyroscopic_step():
    """The intermediate-axis plank's angular velocity changes in free flight (Dzhanibekov):
    with the gyroscopic step compiled in, its kinetic energy stays put while w turns."""
    plank = [box_body([0.0, 0.0, 0.0], half=(1.0, 0.25, 0.1), angular_velocity=[0.01, 3.0, 0.01])]
    world = _world(plank, statics=(), gravity=(0.0, 0.0, 0.0))
    assert world.compiled_effects.gyroscopic
    ke0 = world.metrics()["kinetic_energy"]
    spin = []  # the angular velocity's component along the plank's own y axis
    for _ in range(240):
        world.step(1)
        state = world.state()
        spin.append(quat_to_matrix(state["orientation"][0])[:, 1] @ state["angular_velocity"][0])
    # within 4 s the spin about its own y axis has reversed (Dzhanibekov's flip); without the
    # gyroscopic term its body-frame angular velocity would stay (0.01, 3, 0.01) for ever
    assert spin[0] > 2.9 and min(spin) < -0.5
    assert world.metrics()["kinetic_energy"] == pytest.approx(ke0, rel=1e-3)
