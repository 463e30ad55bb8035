"""A pair found already overlapping pushes out no faster than ``Settings.overlap_push_speed``
(sandbox/manifold_cache.py marks it, solvers/normal_target.py bias_push caps it); contacts that arrive
as speculative gaps and are pressed in by an impact are never marked, nor are the resting
contacts of a world rebuilt around a settled stack."""

import dataclasses

import numpy as np
import pytest

from sandbox import Scene, Settings, World

from tests.helpers import TEST_ARCH, assert_same_state, box_body, scene_dict


def _sunk_box(solver: str, cap: float) -> tuple[list[float], list[int], World]:
    """A unit cube placed 30 cm into the ground, 120 steps: its upward speed and its marked
    contact points after every step."""
    scene = Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.2])], solver=solver, iterations=10))
    world = World(scene, arch=TEST_ARCH, settings=Settings(overlap_push_speed=cap))
    rise, marked = [], []
    for _ in range(120):
        world.step(1)
        rise.append(float(world.state()["linear_velocity"][0, 2]))
        marked.append(int(world.contacts(fields=["overlap"])["overlap"].sum()))
    return rise, marked, world


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_a_box_placed_in_the_ground_is_marked_until_out_and_rises_no_faster_than_the_cap(solver):
    rise, marked, world = _sunk_box(solver, cap=1.0)
    assert marked[0] == 4  # the four corners of the face below the ground, from the first step
    out = marked.index(0)
    assert all(m == 0 for m in marked[out:])  # once out, never marked again
    assert max(rise) <= 1.0
    assert world.state()["position"][0, 2] == pytest.approx(0.5, abs=2e-3)  # rests on the ground
    # the cap is what keeps it slow: at max_push_speed (3 m/s) mass splitting's split relax sweep
    # leaves it rising at ~1 m/s, serial PGS's at ~0.3 m/s (both about three times as fast)
    fast_rise, _, _ = _sunk_box(solver, cap=3.0)
    assert max(fast_rise) > 2.0 * max(rise)


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_an_impact_is_caught_as_a_gap_and_never_marked(solver):
    """A cube placed 10 cm above the ground at 30 m/s is found as a speculative gap in the first
    step, while it still counts as placed: its pair is not new when it touches, nor when it
    lands again after a bounce (no body is placed by then)."""
    scene = Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.6], linear_velocity=[0.0, 0.0, -30.0])],
                                       solver=solver, iterations=10))
    world = World(scene, arch=TEST_ARCH)
    deepest = 0.0
    for _ in range(180):  # mass splitting throws it up (warm start: docs/method-notes.md) and it lands again
        world.step(1)
        c = world.contacts(fields=["overlap", "separation"])
        deepest = max([deepest, *(-c["separation"])])
        assert c["overlap"].sum() == 0
    assert deepest > 0.0  # it touched


def test_an_edit_marks_only_the_pairs_of_the_body_it_placed():
    """An edit rebuilds the world and forgets its manifolds, so every pair is new at the next
    step; only the pair of the box dropped 20 cm into the top of a settled stack is marked, not
    the stack's own contacts, pressed beyond the slop by its load."""
    bodies = [box_body([0.0, 0.0, 0.5 + k]) for k in range(6)]
    world = World(Scene.from_dict(scene_dict(bodies, solver="mass-splitting", iterations=15)), arch=TEST_ARCH)
    world.step(120)
    assert world.contacts(fields=["separation"])["separation"].min() < -world.settings.slop
    [new] = world.add_bodies([dataclasses.replace(world.body_specs[5], position=np.array([0.0, 0.0, 6.3]))])
    world.step(1)
    c = world.contacts(fields=["overlap", "body_a", "body_b"])
    of_new = (c["body_a"] == new) | (c["body_b"] == new)
    assert c["overlap"][of_new].all() and of_new.sum() == 4
    assert not c["overlap"][~of_new].any()


def test_a_world_built_from_a_settled_stack_marks_none_of_its_contacts():
    """Every body of a new world is placed, so depth alone decides: the stack's contacts,
    pressed beyond the slop by its load, rest within the overlap depth."""
    bodies = [box_body([0.0, 0.0, 0.5 + k]) for k in range(6)]
    world = World(Scene.from_dict(scene_dict(bodies, solver="mass-splitting", iterations=15)), arch=TEST_ARCH)
    world.step(120)
    settled = dataclasses.replace(world.scene, bodies=world._live_specs())
    twin = World(settled, arch=TEST_ARCH)
    twin.step(1)
    c = twin.contacts(fields=["overlap", "separation"])
    assert c["separation"].min() < -twin.settings.slop
    assert not c["overlap"].any()


def test_marks_survive_an_edit_while_the_overlap_is_pushed_out():
    """An edit forgets the manifolds; the bodies of the pairs still marked count as placed
    again (Edits.keep_overlaps), so the same pairs are marked after it."""
    from sandbox.hard_cases import deep_overlap

    world = World(Scene.from_dict(deep_overlap().scene, source="deep_overlap"), solver="mass-splitting",
                  iterations=15, arch=TEST_ARCH)
    world.step(3)
    before = world.contacts(fields=["overlap", "body_a", "body_b"])
    assert before["overlap"].sum() > 10
    world.add_bodies([dataclasses.replace(world.body_specs[0], position=np.array([20.0, 0.0, 0.5]))])
    world.step(1)
    after = world.contacts(fields=["overlap", "body_a", "body_b"])
    pairs = {tuple(p) for p in zip(before["body_a"][before["overlap"] == 1], before["body_b"][before["overlap"] == 1])}
    still = {tuple(p) for p in zip(after["body_a"][after["overlap"] == 1], after["body_b"][after["overlap"] == 1])}
    assert still and still <= pairs


def test_placed_overlaps_give_the_profiled_bits():
    """The fused narrowphase (step_kernels.begin_and_collide, its overlap depth from the step
    scalars) marks what the profiled one does."""
    from sandbox.hard_cases import deep_overlap

    scene = Scene.from_dict(deep_overlap().scene, source="deep_overlap")
    states = []
    for profile in (True, False):
        world = World(scene, solver="mass-splitting", iterations=8, arch=TEST_ARCH, profile=profile)
        world.step(20)
        states.append(world.state())
    assert_same_state(*states)
