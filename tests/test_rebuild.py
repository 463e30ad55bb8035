"""An edit rebuilds the world's buffers (sandbox/edits.py); what it must carry over for the bodies
that stay: their contacts' warm-start impulses (persistence.read_history / write_history, the
shapes renumbered) and their support loads (the springs' stiffness and preload).

Before they were carried, adding a box 30 m from a resting 10-box column (or 300 of them, which
moves the world to larger buffers), or removing one (which renumbers every body after it), left the column 3.9 mm from where it would have been 30 steps
later (it started the next step cold and soft, and fell for a substep); carried, it is within
1-13 um of that (the manifolds are found again, not reused, so not to the bit).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from sandbox import Scene, World
from tests.helpers import TEST_ARCH, box_body, scene_dict

SETTLE, AFTER = 120, 30
UNDISTURBED = 1e-4
"""[m] how far from its unedited run the column may end: a tenth of a millimetre, invisible, and
~40x below what a cold restart did (3.9 mm)."""


def _column_world(solver: str) -> World:
    bodies = [box_body([30.0, 0.0, 0.5])] + [box_body([0.0, 0.0, 0.5 + i]) for i in range(10)]
    world = World(Scene.from_dict(scene_dict(bodies, solver=solver, iterations=15)), arch=TEST_ARCH)
    world.set_effects([e for e in world.effects if e != "sleeping"])  # asleep, it would not move anyway
    world.step(SETTLE)
    return world


def _column_after(solver: str, edit: str) -> tuple[np.ndarray, dict, dict]:
    """The column's positions AFTER steps after ``edit``, and its support loads just before and
    just after the edit."""
    world = _column_world(solver)
    column = slice(1, 11)
    loads_before = world._edits.buf.bodies.read_loads(11)
    caps = world._edits.buf.caps
    if edit == "add":
        world.add_bodies([copy.deepcopy(world._edits.bodies[0])])
    elif edit == "grow":  # enough bodies for a larger buffer class: new buffers, not an upload
        far = []
        for k in range(300):
            box = copy.deepcopy(world._edits.bodies[0])
            box.position = np.array([30.0 + 2.0 * (k % 20), 2.0 * (k // 20), 0.5])
            far.append(box)
        world.add_bodies(far)
        assert world._edits.buf.caps != caps, "300 more boxes should move the world to larger buffers"
    elif edit == "remove":
        world.remove_bodies([0])
        column = slice(0, 10)
    loads_after = {k: v[column] for k, v in world._edits.buf.bodies.read_loads(11).items()}
    world.step(AFTER)
    return world.state()["position"][column], {k: v[1:11] for k, v in loads_before.items()}, loads_after


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_an_edit_elsewhere_leaves_a_resting_column_where_it_was(solver):
    unedited, _, _ = _column_after(solver, "none")
    for edit in ("add", "grow", "remove"):
        edited, before, after = _column_after(solver, edit)
        for name in before:
            np.testing.assert_array_equal(after[name], before[name], err_msg=f"{edit}: {name} not carried")
        moved = float(np.abs(edited - unedited).max())
        assert moved < UNDISTURBED, f"{solver}, {edit}: the column ended {1e3 * moved:.3f} mm from its unedited run"


def test_a_world_in_a_pooled_buffer_starts_with_no_contacts():
    """Closed worlds give their buffers back to a pool (buffers.py), and the next world of the same
    size takes them: before its first step it showed the previous world's contacts, with that
    world's body indices, and ``metrics()`` hung labelling islands over them."""
    stack = World(Scene.from_dict(scene_dict([box_body([0.0, 0.0, 0.5 + i]) for i in range(3)])), arch=TEST_ARCH)
    stack.step(30)
    assert stack.metrics()["contacts"] > 0
    pooled = stack.buf
    stack.close()
    falling = World(Scene.from_dict(scene_dict([box_body([5.0, 0.0, 3.0])])), arch=TEST_ARCH)
    assert falling.buf is pooled, "the second world should take the first one's buffers"
    assert len(falling.contacts()["normal"]) == 0
    assert falling.metrics()["contacts"] == 0
