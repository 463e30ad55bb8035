"""Manifold reuse (sandbox/manifold_cache.py): resting pairs keep their contact points,
moving pairs go through SAT and clipping, and a kept manifold is the one the
narrowphase would find at the same pose."""

import dataclasses

import numpy as np
import pytest

from sandbox import Scene, Settings, World
from sandbox.errors import SandboxError

from tests.helpers import TEST_ARCH, box_body, scene_dict


def _stack_scene():
    """A 3-box stack beside a box lying across two others: face, and edge-on-face, contacts."""
    bodies = [box_body([0.0, 0.0, 0.5 + 1.0 * k]) for k in range(3)]
    bodies += [box_body([3.0, -0.6, 0.25], half=(0.25, 0.25, 0.25)), box_body([3.0, 0.6, 0.25], half=(0.25, 0.25, 0.25)),
               box_body([3.0, 0.0, 0.65], half=(0.15, 1.0, 0.15), orientation=[0.9238795, 0.0, 0.3826834, 0.0])]
    return Scene.from_dict(scene_dict(bodies, solver="mass-splitting", iterations=15))


def test_a_resting_scene_reuses_every_manifold_and_they_match_a_fresh_narrowphase():
    scene = _stack_scene()
    world = World(scene, arch=TEST_ARCH)
    world.step(120)
    # a twin world at exactly this state (positions with their remainders) has no manifolds to reuse
    twin = World(dataclasses.replace(scene, bodies=world._live_specs()), arch=TEST_ARCH)
    world.step(1)
    twin.step(1)
    m = world.metrics()
    assert m["manifolds"] == 7  # 3 stack pairs, 2 boxes on the plane, the bar on both boxes
    assert m["manifolds_reused"] == m["manifolds"]
    assert twin.metrics()["manifolds_reused"] == 0
    kept, fresh = world.contacts(), twin.contacts()
    for key in ("body_a", "body_b", "manifold"):
        np.testing.assert_array_equal(kept[key], fresh[key])
    # the kept points and normals ride with their bodies: they differ from a fresh clip by at
    # most the relative motion since they were found, which reuse bounds (the bar, 1.03 m
    # from its centre to a corner, turned ~6e-4 rad while settling); the depths are measured
    # again, not remembered, so they agree to float32 rounding
    s = Settings()
    np.testing.assert_allclose(kept["point"], fresh["point"], rtol=0,
                               atol=s.manifold_reuse_distance + 1.05 * s.manifold_reuse_angle)
    np.testing.assert_allclose(kept["normal"], fresh["normal"], rtol=0, atol=s.manifold_reuse_angle)
    np.testing.assert_allclose(kept["separation"], fresh["separation"], rtol=0, atol=1e-6)


def test_a_sliding_box_goes_through_the_narrowphase_every_step_until_it_stops():
    body = box_body([0.0, 0.0, 0.5], linear_velocity=[2.0, 0.0, 0.0])
    world = World(Scene.from_dict(scene_dict([body], solver="pgs", iterations=10)), arch=TEST_ARCH)
    for _ in range(20):  # friction 0.5 stops 2 m/s in ~0.41 s (24 steps); until then >1 mm per step
        world.step(1)
        assert world.metrics()["manifolds_reused"] == 0
    world.step(60)
    assert np.linalg.norm(world.state()["linear_velocity"][0]) < 1e-3
    assert world.metrics()["manifolds_reused"] == world.metrics()["manifolds"] == 1


def test_reuse_off_and_on_agree_on_a_resting_stack():
    """Reuse changes how contacts are found, not the physics: the stack settles to the same
    heights either way (to well under the slop)."""
    scene = _stack_scene()
    on = World(scene, arch=TEST_ARCH)
    off = World(scene, arch=TEST_ARCH, settings=Settings(manifold_reuse_distance=0.0))
    on.step(300)
    off.step(300)
    assert off.metrics()["manifolds_reused"] == 0
    np.testing.assert_allclose(on.state()["position"], off.state()["position"], rtol=0, atol=5e-5)
    assert on.metrics()["kinetic_energy"] < 1e-6 and off.metrics()["kinetic_energy"] < 1e-6


def test_a_rebuild_forgets_the_manifolds():
    world = World(_stack_scene(), arch=TEST_ARCH)
    world.step(60)
    assert world.metrics()["manifolds_reused"] == 7
    world.add_bodies([dataclasses.replace(world.body_specs[0], position=np.array([-5.0, 0.0, 0.5]))])
    world.step(1)
    assert world.metrics()["manifolds_reused"] == 0


@pytest.mark.parametrize("value", [-0.001, float("nan"), float("inf")])
def test_bad_reuse_tolerances_are_refused(value):
    with pytest.raises(SandboxError, match="manifold_reuse_distance"):
        Settings(manifold_reuse_distance=value)
    with pytest.raises(SandboxError, match="manifold_reuse_angle"):
        Settings(manifold_reuse_angle=value)


def test_a_reuse_angle_past_half_a_turn_is_refused():
    with pytest.raises(SandboxError, match=r"manifold_reuse_angle must be in \[0, 3.1416\]"):
        Settings(manifold_reuse_angle=4.0)


def test_a_pair_kept_apart_by_its_gap_still_meets():
    """A frictionless box slides at 0.3 m/s towards a standing one 8 cm away. Once their
    bounds overlap the pair is searched, found apart (no points), and then skipped on its
    gap while the gap minus the approach since stays above the margin; it is searched
    again in time to get its points, and the slid box stops against the other instead of
    passing into it."""
    standing = box_body([0.0, 0.0, 0.5])
    sliding = box_body([-1.08, 0.0, 0.5], linear_velocity=[0.3, 0.0, 0.0], friction=0.0)
    world = World(Scene.from_dict(scene_dict([standing, sliding], solver="mass-splitting", iterations=15)),
                  arch=TEST_ARCH)
    skipped_apart, touching, deepest = 0, 0, 0.0
    for _ in range(40):
        world.step(1)
        m = world.metrics()
        skipped_apart += m["pairs_reused"] - m["manifolds_reused"]
        c = world.contacts(["body_a", "body_b", "separation"])
        between = (np.minimum(c["body_a"], c["body_b"]) == 0) & (np.maximum(c["body_a"], c["body_b"]) == 1)
        if between.any():
            touching += 1
            deepest = min(deepest, float(c["separation"][between].min()))
    assert skipped_apart >= 2  # 4.3 cm apart when first paired, 2.5 cm margin, 5 mm per step
    assert touching > 0
    assert deepest > -2e-3
    x = world.state()["position"][:, 0]
    assert x[0] - x[1] > 1.0 - 2e-3  # face to face, not into each other


def test_a_turning_pair_kept_apart_is_searched_again_before_it_touches():
    """The gap bound counts turning as well as sliding: a box spinning at 0.3 rad/s beside a
    fixed one 5 cm away is skipped while its turn since the search cannot close the gap, and
    searched again in time; its corner meets the fixed box instead of turning into it (the
    corner's reach 0.5 (cos t + sin t) hits the face at 0.55 m when t = 0.106 rad, step ~21)."""
    spinning = box_body([0.0, 0.0, 0.0], angular_velocity=[0.0, 0.0, 0.3])
    fixed = box_body([1.05, 0.0, 0.0], static=True)
    world = World(Scene.from_dict(scene_dict([spinning, fixed], statics=(), gravity=(0.0, 0.0, 0.0),
                                             solver="mass-splitting", iterations=15)), arch=TEST_ARCH)
    skipped_apart, touching, deepest = 0, 0, 0.0
    for _ in range(60):
        world.step(1)
        m = world.metrics()
        if touching == 0:
            skipped_apart += m["pairs_reused"] - m["manifolds_reused"]
        if m["contacts"]:
            touching += 1
            deepest = max(deepest, m["max_penetration"])
    assert skipped_apart >= 1  # before the first touch (steps 4 and 6 of 21)
    assert touching > 0
    assert deepest < 2e-3
