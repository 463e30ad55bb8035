"""Bad API calls get the library's own error with a clear message and leave the world intact."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sandbox import SandboxError, Scene, World

from tests.helpers import TEST_ARCH, box_body, scene_dict

BAD_NUMBERS = st.sampled_from([math.nan, math.inf, -math.inf, "x", None, [1.0, 2.0], [[1, 2, 3]], True])


@pytest.fixture(scope="module")
def world():
    w = World(Scene.from_dict(scene_dict([box_body([0, 0, 0.5]), box_body([0, 0, 3.0], static=True)])), arch=TEST_ARCH)
    w.step(2)
    return w


def _unchanged(world, before):
    after = world.state()
    for key in before:
        np.testing.assert_array_equal(before[key], after[key])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(bad=BAD_NUMBERS, call=st.sampled_from(["velocity", "angular", "impulse", "point"]))
def test_non_finite_or_malformed_vectors_are_refused(world, bad, call):
    before = world.state()
    vec = [bad, 0.0, 0.0] if not isinstance(bad, list) else bad
    with pytest.raises(SandboxError):
        if call == "velocity":
            world.set_velocity([0], linear=vec)
        elif call == "angular":
            world.set_velocity([0], angular=vec)
        elif call == "impulse":
            world.apply_impulse([0], vec)
        else:
            world.apply_impulse([0], [1.0, 0.0, 0.0], point=vec)
    _unchanged(world, before)


@pytest.mark.parametrize("indices, match", [([5], "no body 5"), ([-1], "no body -1"), (["a"], "no body"),
                                            ([1], "static")])
def test_bad_body_references_are_refused(world, indices, match):
    before = world.state()
    with pytest.raises(SandboxError, match=match):
        world.apply_impulse(indices, [1.0, 0.0, 0.0])
    _unchanged(world, before)


@pytest.mark.parametrize("call", [lambda w: w.step(-1), lambda w: w.step(1.5), lambda w: w.set_solver("nope"),
                                  lambda w: w.set_solver("pgs", iterations=0),
                                  lambda w: w.set_solver("jacobi", relaxation=3.0),
                                  lambda w: w.set_solver("pgs", shuffle=True),
                                  lambda w: w.set_solver("pgs-colored", seed=2**40)])
def test_bad_solver_and_step_arguments_are_refused(world, call):
    with pytest.raises(SandboxError):
        call(world)


@pytest.mark.parametrize("asked, match", [({"iterations": 0}, "iterations must be an integer >= 1, got 0"),
                                          ({"solver": ""}, "solver")])
def test_a_world_refuses_zero_iterations_and_an_empty_solver_name(asked, match):
    """0 and "" are answers, not "the scene's": they once fell back to the scene's solver silently."""
    with pytest.raises(SandboxError, match=match):
        World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5])])), arch=TEST_ARCH, **asked)


def test_world_needs_a_scene():
    with pytest.raises(SandboxError, match="needs a Scene"):
        World({"body": []}, arch=TEST_ARCH)


def test_world_settings_must_be_settings():
    """A dict of settings once failed inside the world's build with a raw AttributeError."""
    with pytest.raises(SandboxError, match=r"settings must be a sandbox.Settings .* got dict"):
        World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5])])), arch=TEST_ARCH, settings={"sweeps": 2})


def test_unknown_settings_are_refused():
    from sandbox import Settings

    with pytest.raises(SandboxError, match="unknown iteration_launch 'threads'.*shared"):
        Settings(iteration_launch="threads")
    with pytest.raises(SandboxError, match="unknown setting"):
        Settings().replace(iteration_lunch="one")


@pytest.mark.parametrize("name, value, match", [
    # checked since session 49 (a NaN spring or 0 sweeps were taken as given before)
    ("contact_hertz", float("nan"), "contact_hertz must be a finite number > 0"),
    ("contact_hertz", -30.0, "contact_hertz must be a finite number > 0"),
    ("slop", -1e-3, "slop must be a finite number >= 0"),
    ("contact_margin", float("inf"), "contact_margin must be a finite number >= 0"),
    ("match_distance", -1.0, "match_distance must be"),
    ("jacobi_relaxation", 0.0, "jacobi_relaxation must be a finite number > 0"),
    ("fracture_min_piece_size", 0.0, "fracture_min_piece_size must be"),
    ("warm_start", 2.0, r"warm_start must be a number in \[0, 1\]"),
    ("max_push_speed", float("nan"), r"max_push_speed must be a number > 0 \(inf: no cap\)"),
    ("sweeps", 0, "sweeps must be a whole number >= 1, got 0"),
    ("sweeps", 2.5, "sweeps must be a whole number >= 1"),
    ("max_bodies", 0, "max_bodies must be a whole number >= 1"),
    ("speculative_contacts", 1, "speculative_contacts must be true or false"),
    ("contact_preload", 1.5, r"contact_preload must be a number in \[0, 1\]"),
                                                ("contact_preload", -0.1, r"in \[0, 1\], got -0.1"),
                                                ("contact_preload", float("nan"), r"contact_preload must be"),
                                                ("contact_preload_lag", 0.0, "contact_preload_lag must be a finite "
                                                                              "number > 0"),
                                                ("contact_preload_lag", float("inf"), "contact_preload_lag must"),
                                                ("contact_rocking_stiffness", -0.5, "contact_rocking_stiffness must be a "
                                                                                    "finite number >= 0"),
                                                ("contact_rocking_stiffness", float("nan"), "contact_rocking_stiffness"),
                                                ("contact_damping_ratio", -1.0, "contact_damping_ratio must be a "
                                                                                "finite number >= 0"),
                                                ("contact_damping_ratio", float("inf"), "contact_damping_ratio must"),
                                                ("light_damping_ratio", -1.0, "light_damping_ratio must be a "
                                                                              "finite number >= 0"),
                                                ("light_damping_ratio", float("nan"), "light_damping_ratio must"),
                                                # 0 would make every resting contact an impact, its warm start dropped
                                                ("restitution_threshold", 0.0, "restitution_threshold must be a finite "
                                                                               "number > 0"),
                                                ("restitution_threshold", float("nan"), "restitution_threshold must")])
def test_bad_contact_settings_are_refused(name, value, match):
    from sandbox import Settings

    with pytest.raises(SandboxError, match=match):
        Settings().replace(**{name: value})
