"""A pair found already overlapping pushes out no faster than ``Settings.overlap_push_speed``
(sandbox/manifold_cache.py marks it, solvers/rows.py bias_push caps it); contacts that arrive
as speculative gaps and are pressed in by an impact are never marked, nor are the resting
contacts of a world rebuilt around a settled stack."""

import dataclasses

import numpy as np
import pytest

from sandbox import Scene, Settings, World

from tests.helpers import box_body, scene_dict


def _sunk_box(solver: str, cap: float) -> tuple[list[float], list[int], World]:
    """A unit cube placed 30 cm into the ground, 120 steps: its upward speed and its marked
    contact points after every step."""
    scene = Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.2])], solver=solver, iterations=10))
    world = World(scene, arch="cpu", settings=Settings(overlap_push_speed=cap))
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
    """A cube hitting the ground at 30 m/s is found as a speculative gap the step before it
    touches: its pair is not new when it is pressed in, however deep."""
    scene = Scene.from_dict(scene_dict([box_body([0.0, 0.0, 2.0], linear_velocity=[0.0, 0.0, -30.0])],
                                       solver=solver, iterations=10))
    world = World(scene, arch="cpu")
    deepest = 0.0
    for _ in range(60):
        world.step(1)
        deepest = max(deepest, world.metrics()["max_penetration"])
        assert world.contacts(fields=["overlap"])["overlap"].sum() == 0
    assert deepest > world.settings.slop  # it was pressed in


def test_an_edit_marks_only_the_pairs_of_the_body_it_placed():
    """An edit rebuilds the world and forgets its manifolds, so every pair is new at the next
    step; only the pair of the box dropped 20 cm into the top of a settled stack is marked, not
    the stack's own contacts, pressed beyond the slop by its load."""
    bodies = [box_body([0.0, 0.0, 0.5 + k]) for k in range(6)]
    world = World(Scene.from_dict(scene_dict(bodies, solver="mass-splitting", iterations=15)), arch="cpu")
    world.step(120)
    assert world.contacts(fields=["separation"])["separation"].min() < -world.settings.slop
    [new] = world.add_bodies([dataclasses.replace(world.body_specs[5], position=np.array([0.0, 0.0, 6.3]))])
    world.step(1)
    c = world.contacts(fields=["overlap", "body_a", "body_b"])
    of_new = (c["body_a"] == new) | (c["body_b"] == new)
    assert c["overlap"][of_new].all() and of_new.sum() == 4
    assert not c["overlap"][~of_new].any()
