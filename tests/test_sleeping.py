"""Islands and sleeping (issue 16): labels on a hand-made graph, and three columns of boxes that
fall asleep, are woken by what touches them, keep their warm start, and replay bit for bit."""

import numpy as np
import pytest

from sandbox import Scene, World
from sandbox.recording import Recorder, replay
from sandbox.scene.spec import EventSpec

from tests.helpers import TEST_ARCH, assert_same_metrics, assert_same_state, box_body, compiled_kernel_count, scene_dict

COLUMNS = (-3.0, 0.0, 3.0)  # three columns of three unit boxes, 2 m apart: three islands
SLEEPING = ["friction", "restitution", "sleeping"]
SETTLE = 40
"""Steps after which every column sleeps: 0.5 s of rest (Settings.sleep_time) is 30 steps at 60 Hz,
and the columns start at rest."""

SCENE_TOML = """
effects = ["friction", "restitution", "sleeping"]
[world]
gravity = [0.0, 0.0, -9.81]
dt = 0.016666666666666666
[solver]
name = "pgs"
iterations = 10
[[static]]
shape = "plane"
normal = [0.0, 0.0, 1.0]
{bodies}
[[event]]
time = 0.75
kind = "drop"
count = 1
region = [[-3.45, -0.45, 4.0], [-2.55, 0.45, 4.85]]
shapes = ["box"]
half_extents = 0.4
orientation = "identity"
seed = 1
"""
"""The columns, and at 0.75 s (asleep by then) a box dropped about 0.7 m above the first column."""


def _columns():
    return [box_body([x, 0.0, 0.5 + k]) for x in COLUMNS for k in range(3)]


def _world(effects=SLEEPING, solver="pgs"):
    d = scene_dict(_columns(), solver=solver)
    d["effects"] = list(effects)
    return World(Scene.from_dict(d), arch=TEST_ARCH)


def _same(a: dict, b: dict) -> bool:
    return all(np.array_equal(a[k], b[k]) for k in a)


# ---------------------------------------------------------------------------- islands
def test_island_labels_on_a_hand_made_contact_graph():
    """Bodies 0..11, body 11 static; the labels are each island's smallest body index, -1 for the
    static body, which joins nothing (2 and 9 both touch it and stay apart)."""
    from sandbox.awake import EVERY
    from sandbox.bodies import Bodies
    from sandbox.contacts import Contacts
    from sandbox.islands import Islands, label_islands

    n, static = 12, 11
    edges = [(10, 9), (9, 8), (8, 7), (7, 6), (5, 3), (3, 0), (1, 4), (2, static), (static, 9), (4, 4)]
    bodies, contacts, isl = Bodies(16), Contacts(16, 16), Islands(16)
    inv_mass = np.zeros(16, np.float32)
    inv_mass[:n] = 1.0
    inv_mass[static] = 0.0
    bodies.inv_mass.from_numpy(inv_mass)
    bodies.count[None] = n
    for field, column in ((contacts.m_body_a, 0), (contacts.m_body_b, 1)):
        values = np.zeros(field.shape[0], np.int32)
        values[: len(edges)] = [e[column] for e in edges]
        field.from_numpy(values)
    contacts.manifold_count[None] = len(edges)
    expected = np.array([0, 1, 2, 0, 1, 0, 6, 6, 6, 6, 6, -1])
    for _ in range(2):  # the same labels again: nothing depends on the previous call or on timing
        assert label_islands(isl, contacts, bodies, EVERY) == 4
        assert np.array_equal(isl.label.to_numpy()[:n], expected)
        # numbered by a prefix sum over the roots (0, 1, 2, 6) in body order
        assert np.array_equal(isl.number.to_numpy()[:n], [0, 1, 2, 0, 1, 0, 3, 3, 3, 3, 3, -1])


# ---------------------------------------------------------------------------- sleeping
@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_sleeping_changes_no_bit_until_an_island_sleeps(solver):
    """The awake lists run the same arithmetic as the full loops; then every column sleeps at rest."""
    on, off = _world(solver=solver), _world(effects=["friction", "restitution"], solver=solver)
    while True:
        on.step(1)
        off.step(1)
        if on.asleep().any():
            break
        assert _same(on.state(), off.state()), f"step {on.step_count}"
    # the step that put them to sleep ran the same too; only then were the velocities zeroed
    assert on.step_count > 20 and np.array_equal(on.state()["position"], off.state()["position"])
    on.step(SETTLE - on.step_count)
    m = on.metrics()
    assert on.asleep().all() and (m["awake_bodies"], m["sleeping_bodies"], m["islands"]) == (0, 9, 3)
    assert not np.any(on.state()["linear_velocity"]) and not np.any(on.state()["angular_velocity"])
    assert list(on.island_labels()) == [0, 0, 0, 3, 3, 3, 6, 6, 6]
    assert off.metrics()["sleeping_bodies"] == 0 and off.metrics()["islands"] == 3


def test_a_dropped_box_wakes_the_island_it_touches_and_replays_bit_for_bit(tmp_path):
    bodies = "\n".join(f'[[body]]\nshape = "box"\nhalf_extents = [0.5, 0.5, 0.5]\nposition = [{x}, 0.0, {0.5 + k}]'
                       for x in COLUMNS for k in range(3))
    path = tmp_path / "columns.toml"
    path.write_text(SCENE_TOML.format(bodies=bodies))
    runs = []
    for _ in range(2):
        world = World(Scene.load(path), arch=TEST_ARCH)
        recorder = Recorder(world, path)  # frame 0, then one frame per step
        for _ in range(SETTLE):
            world.step(1)
            recorder.capture()
        assert world.asleep().all()
        rested = world.state()["position"].copy()
        woke = np.zeros(9, dtype=bool)
        for _ in range(60):  # the drop at step 45 lands about 20 steps later
            world.step(1)
            recorder.capture()
            woke |= ~world.asleep()[:9]
        moved = np.abs(world.state()["position"][:9] - rested).max(axis=1)
        assert woke[:3].all() and not woke[3:9].any()  # the first column woke, the others never did
        assert moved[:3].min() > 0.0 and not moved[3:].any()  # ... and moved; the others did not, by a bit
        runs.append(world.state())
    assert _same(*runs)
    recorded = tmp_path / "columns.sbrec"
    recorder.save(recorded)
    result = replay(recorded, arch=TEST_ARCH)
    assert result["first_departure"] is None and result["max_difference"] == 0.0


def test_preparing_compiles_falling_asleep_and_waking_and_changes_no_bit(tmp_path):
    """World.prepare_edits runs the fall-asleep and wake kernels before anything sleeps (the
    web sandbox: a ~1 s stall at the playground's first island at rest): the prepared world
    compiles no new instance of either when its columns sleep and the drop wakes one, and every
    state on the way is the unprepared world's, bit for bit."""
    from sandbox import sleep

    bodies = "\n".join(f'[[body]]\nshape = "box"\nhalf_extents = [0.5, 0.5, 0.5]\nposition = [{x}, 0.0, {0.5 + k}]'
                       for x in COLUMNS for k in range(3))
    path = tmp_path / "columns.toml"
    path.write_text(SCENE_TOML.format(bodies=bodies))
    kernels = (sleep._fall_asleep._primal, sleep._wake._primal)
    runs = []
    for prepare in (True, False):
        world = World(Scene.load(path), arch=TEST_ARCH)
        if prepare:
            world.prepare_edits()
            compiled = [len(k.compiled_kernels) for k in kernels]
        states, slept, woke = [], False, False
        for _ in range(SETTLE + 60):
            world.step(1)
            states.append((world.state(), world.asleep()))
            slept |= bool(world.asleep().all())
            woke |= slept and not world.asleep()[:3].any()
        assert slept and woke
        if prepare:  # its own instances (a world's buffers are template arguments) were all there
            assert [len(k.compiled_kernels) for k in kernels] == compiled
        runs.append(states)
    for (state, asleep), (state_plain, asleep_plain) in zip(*runs):
        assert _same(state, state_plain) and np.array_equal(asleep, asleep_plain)


def test_switching_sleeping_off_compiles_nothing_and_steps_as_a_world_that_never_slept():
    """A world that has slept keeps its awake lists when sleeping goes off (sleep.stop): the
    step's kernels stay the instances they were (the web playground paused 3.3 s, 10.5 s with a
    cold kernel cache, when the toggle moved its kernels back to awake.EVERY), and it steps bit
    for bit as a world that never slept, before and after a rebuild adds a body (the lists are
    made again, of every body: sleep.start with resting=False)."""
    slept, never = _world(), _world(effects=["friction", "restitution"])
    for world in (slept, never):
        world.step(1)
        world.state(), world.metrics(), world.island_labels()  # (reads compile Taichi's copy kernels)
    compiled = compiled_kernel_count()
    slept.set_effects(["friction", "restitution"])
    for _ in range(SETTLE):  # long enough for a column to have fallen asleep
        for world in (slept, never):
            world.step(1)
        assert_same_state(never.state(), slept.state())
    assert_same_metrics(never.metrics(), slept.metrics())  # its islands counted over its lists: 3, none asleep
    assert np.array_equal(slept.island_labels(), never.island_labels())
    assert compiled_kernel_count() == compiled
    assert not slept.asleep().any() and slept.metrics()["islands"] == 3
    box = Scene.from_dict(scene_dict([box_body([-3.0, 0.0, 4.0], half=(0.4, 0.4, 0.4))])).bodies[0]
    for world in (slept, never):
        world.add_bodies([box])
    for step in range(60):
        for world in (slept, never):
            world.step(1)
        assert_same_state(never.state(), slept.state(), f"step {step} after the drop")
    assert slept.state()["position"][-1, 2] < 3.5  # the box fell onto the column


def test_removing_the_bottom_box_wakes_the_column_and_it_falls():
    world = _world()
    world.step(SETTLE)
    top = world.state()["position"][5, 2]
    world.apply_event(EventSpec(time=0.0, kind="remove", bodies=[3]))  # the middle column's bottom box
    assert list(world.asleep()) == [True] * 3 + [False] * 2 + [True] * 3
    world.step(60)
    # one box lower: within a centimetre (1 % of the fall) the column has landed, not still falling
    assert world.state()["position"][4, 2] == pytest.approx(top - 1.0, abs=0.01)


def test_edits_and_changes_wake_what_they_touch():
    world = _world()
    world.step(SETTLE)
    world.set_velocity([7], linear=[0.0, 0.0, 0.0])  # even a zero velocity is an edit of the column
    assert list(world.asleep()) == [True] * 6 + [False] * 3
    world.step(SETTLE)
    world.apply_impulse([1], [0.0, 0.0, 0.0])
    assert list(world.asleep()) == [False] * 3 + [True] * 6
    world.step(SETTLE)
    world.wake([4])
    assert list(world.asleep()) == [True] * 3 + [False] * 3 + [True] * 3
    world.step(SETTLE)
    world.set_gravity([0.0, 0.0, -9.0])
    assert not world.asleep().any()
    world.step(SETTLE)
    world.set_effects(["friction", "restitution"])  # sleeping off: every island wakes
    assert not world.asleep().any() and world.effects == ("friction", "restitution")


RECORD_FIELDS = ("partner", "feature", "anchor", "lam_n", "lam_t")
"""The warm-start records of a shape (persistence.ContactHistory)."""


def _records(world, shapes) -> dict:
    """Each shape's warm-start records now, field by field."""
    hist = world.buf.history
    first, last = hist.shape_first.to_numpy(), hist.shape_last.to_numpy()
    stored = {k: getattr(hist, k).to_numpy() for k in RECORD_FIELDS}
    return {i: {k: stored[k][first[i]:last[i]] for k in RECORD_FIELDS} for i in shapes}


def test_a_woken_island_starts_from_its_stored_impulses_and_manifolds():
    """The records the columns fell asleep with come back exactly when they wake, so the first
    step after takes every manifold back from the cache instead of searching again. The reuse
    distance is widened to 1 cm: at the shipped 1 mm, whether a top box's pair falls asleep just
    inside or just outside it depends on its last steps (one history left it 1.0035 mm from the
    pose its manifold was found at, and that manifold was searched again after the wake)."""
    world = _world()
    world.settings = world.settings.replace(manifold_reuse_distance=0.01)
    while not world.asleep().all():
        world.step(1)
    shapes = range(9)  # the boxes' shapes, one each
    before = _records(world, shapes)
    world.step(5)  # asleep: the steps find no contacts, and the history is emptied
    assert world.metrics()["contacts"] == 0 and not np.any(world.buf.history.shape_last.to_numpy()[:9])
    world.wake()
    after = _records(world, shapes)
    for i in shapes:
        for k in RECORD_FIELDS:
            assert np.array_equal(after[i][k], before[i][k]), (i, k)
    world.step(1)
    m = world.metrics()
    assert m["manifolds"] == 9 and m["manifolds_reused"] == 9


def test_a_rebuild_carries_the_sleeping_islands_over_with_their_new_indices():
    """Removing the first column's bottom box wakes that column only; the other two stay asleep
    through the rebuild, and their stored records follow their bodies down one index (the reuse
    distance widened as in the test above)."""
    world = _world()
    world.settings = world.settings.replace(manifold_reuse_distance=0.01)
    while not world.asleep().all():
        world.step(1)
    before = _records(world, range(3, 9))
    world.remove_bodies([0])
    assert list(world.asleep()) == [False] * 2 + [True] * 6
    world.wake()
    after = _records(world, range(2, 8))  # one index down
    for i, old in before.items():
        now = after[i - 1]
        partner = old["partner"]
        assert np.array_equal(now["partner"], np.where(partner >= 0, partner - 1, partner)), i  # planes stay < 0
        for k in RECORD_FIELDS[1:]:
            assert np.array_equal(now[k], old[k]), (i, k)
    world.step(1)
    assert world.metrics()["manifolds_reused"] == 6  # the two columns' pairs; the first column's cache was cleared


def test_skipping_the_steps_of_an_all_asleep_world_changes_no_bit():
    """Once a step ran with nothing awake, the next ones are skipped (SleepBuffers.idle) until
    something wakes; a world forced to run them ends bit for bit the same."""
    skipping, running = _world(), _world()

    def step(n):
        for _ in range(n):
            running.buf.sleep.idle = False  # never idle: every step's kernels run
            running.step(1)
            skipping.step(1)

    step(SETTLE + 20)
    assert skipping.asleep().all() and skipping.buf.sleep.idle
    skipping.set_velocity([4], linear=[0.5, 0.0, 0.0])
    running.set_velocity([4], linear=[0.5, 0.0, 0.0])
    assert not skipping.buf.sleep.idle  # the edit woke the middle column
    step(60)
    assert _same(skipping.state(), running.state())
    assert skipping.metrics()["sleeping_bodies"] == running.metrics()["sleeping_bodies"]


def test_a_sleeping_world_whose_buffers_grow_keeps_stepping():
    """Four boxes land on a fine mesh (~900 box-triangle pairs each, past the pair buffer of a
    five-body world), so the first step grows the buffers. The grown buffers' sleep state began
    with its rest timers and islands switched off: the step after counted no awake island and
    every later one was skipped as idle, so the world froze (headline_pile at step 22, its 1000
    boxes in mid-air). The fifth box, 20 m up, must keep falling freely."""
    floor = {"shape": "mesh", "position": [0.0, 0.0, 0.0],
             "heightfield": {"function": "sines", "amplitude": 0.0, "size": [4.0, 4.0], "cells": [80, 80]}}
    boxes = [box_body([x, y, 0.52]) for x in (-1.0, 1.0) for y in (-1.0, 1.0)] + [box_body([0.0, 0.0, 20.0])]
    scene = scene_dict(boxes, statics=[floor])
    scene["effects"] = ["friction", "sleeping"]
    world = World(Scene.from_dict(scene), arch=TEST_ARCH)
    first_pairs = world.buf.caps.pairs
    steps = 30
    world.step(steps)
    assert world.buf.caps.pairs > first_pairs  # the case: the buffers grew
    t = steps * world.dt
    free_fall = 20.0 - 0.5 * 9.81 * t * t  # the substeps' discretisation leaves it 4 mm higher
    assert abs(world.state()["position"][4, 2] - free_fall) < 0.01, "the world froze after its buffers grew"
