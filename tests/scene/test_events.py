"""Timeline events, effects, [world] duration, and the wall and rain generators.

Events parse, sort (stably) and resolve body references (names and indices, across drops
and removals); every bad event raises one SceneError naming the file, the entry and the
problem. Wall and rain give the right counts and never start with overlapping bodies.
"""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sandbox.errors import SceneError
from sandbox.scene import EventSpec, load_scene, scene_from_dict
from sandbox.scene import generators
from sandbox.scene.loader import EFFECTS, EVENT_KINDS, GENERATOR_KINDS
from sandbox.scene.rotations import quat_to_matrix
from tests.helpers import TEST_ARCH, anchor_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
SOURCE = "events.toml"

BOX = {"shape": "box", "half_extents": [0.5, 0.5, 0.5]}
_DROP = object()
"""A key value meaning: leave this key out."""


def _clean(entry: dict) -> dict:
    return {k: v for k, v in entry.items() if v is not _DROP}


def _box(x, name=None, **extra) -> dict:
    body = dict(BOX, position=[x, 0.0, 0.5], **extra)
    if name is not None:
        body["name"] = name
    return body


def _drop(time, name=None, count=2, z=20.0, seed=1, **extra) -> dict:
    event = {"time": time, "kind": "drop", "count": count, "region": [[0, 0, z], [4, 4, z + 2]], "seed": seed,
             "half_extents": 0.2, **extra}
    if name is not None:
        event["name"] = name
    return _clean(event)


def _scene(events, bodies=None, **top) -> dict:
    """Three named boxes a, b, c (indices 0, 1, 2), a static box 'floor' (index 3), a mesh 'ground'."""
    data = {
        "body": bodies if bodies is not None else [_box(0, "a"), _box(2, "b"), _box(4, "c")],
        "static": [
            {"shape": "plane", "normal": [0, 0, 1]},
            {"shape": "box", "half_extents": [1, 1, 1], "position": [0, 10, -1], "name": "floor"},
            {"shape": "mesh", "name": "ground", "heightfield": {"function": "sines", "amplitude": 0.1,
                                                               "size": [2, 2], "cells": [2, 2]}},
        ],
        "event": events,
    }
    data.update(top)
    return data


def _load(data):
    return scene_from_dict(copy.deepcopy(data), source=SOURCE)


def _aabbs(bodies) -> tuple[np.ndarray, np.ndarray]:
    """World-axis bounding boxes (low, high) of single-shape bodies, from their exact extents."""
    low, high = [], []
    for body in bodies:
        (shape,) = body.shapes
        rot = quat_to_matrix(body.orientation)
        centre = body.position + rot @ shape.local_position
        if shape.kind == "hull":
            world = shape.vertices @ (rot @ quat_to_matrix(shape.local_orientation)).T
            low.append(centre + world.min(axis=0))
            high.append(centre + world.max(axis=0))
            continue
        if shape.kind == "box":
            ext = np.abs(rot) @ shape.half_extents
        elif shape.kind == "sphere":
            ext = np.full(3, shape.radius)
        else:  # capsule
            ext = shape.radius + np.abs(rot[:, 2]) * shape.half_height
        low.append(centre - ext)
        high.append(centre + ext)
    return np.array(low), np.array(high)


def _assert_disjoint(bodies, tol=1e-9):
    """No two bounding boxes overlap by more than ``tol`` on every axis (so no two bodies overlap)."""
    low, high = _aabbs(bodies)
    overlap = np.minimum(high[:, None, :], high[None, :, :]) - np.maximum(low[:, None, :], low[None, :, :])
    both = np.all(overlap > tol, axis=2)
    np.fill_diagonal(both, False)
    pairs = np.argwhere(both)
    assert len(pairs) == 0, f"{len(pairs) // 2} overlapping pairs, e.g. {pairs[0].tolist()}"


# ---------------------------------------------------------------------------- effects and duration
def test_effects_default_both_and_sorted_subsets():
    assert EFFECTS == ("friction", "restitution", "sleeping")
    assert _load({}).effects == ("friction", "restitution")  # sleeping is asked for, never assumed
    assert _load({"effects": ["sleeping", "friction"]}).effects == ("friction", "sleeping")
    assert _load({"effects": ["restitution", "friction"]}).effects == ("friction", "restitution")
    assert _load({"effects": ["friction"]}).effects == ("friction",)
    assert _load({"effects": []}).effects == ()  # frictionless, perfectly inelastic


@pytest.mark.parametrize("value,entry,fragment", [
    (["friction", "rolling"], "effects[1]", "unknown effect 'rolling'; expected one of: friction, restitution, sleeping"),
    (["friction", "friction"], "effects[1]", "listed twice"),
    ("friction", "effects", "expected a list"),
    ([1], "effects[0]", "expected a string"),
])
def test_bad_effects(value, entry, fragment):
    with pytest.raises(SceneError) as info:
        _load({"effects": value})
    assert info.value.entry == entry and SOURCE in str(info.value) and fragment in str(info.value)


def test_world_duration():
    assert _load({}).world.duration is None
    assert _load({"world": {"duration": 2.5}}).world.duration == 2.5
    for bad, fragment in ((0.0, "must be > 0"), (-1.0, "must be > 0"), (math.nan, "finite"), (math.inf, "finite"),
                          ("long", "expected a number")):
        with pytest.raises(SceneError) as info:
            _load({"world": {"duration": bad}})
        assert info.value.entry == "world.duration" and fragment in str(info.value)


# ---------------------------------------------------------------------------- parsing and sorting
def test_events_parse_every_kind_and_sort_stably():
    scene = _load(_scene([
        {"time": 2.0, "kind": "iterations", "iterations": 40},
        {"time": 1.0, "kind": "solver", "name": "pgs-colored", "iterations": 20, "shuffle": True, "seed": 4},
        {"time": 1.0, "kind": "set_velocity", "bodies": ["a"], "linear_velocity": [1, 2, 3]},
        {"time": 0.0, "kind": "impulse", "bodies": [1], "impulse": [0, 0, 5], "point": [2, 0, 1]},
        {"time": 1.0, "kind": "solver", "name": "jacobi", "relaxation": 0.5},
        {"time": 0.5, "kind": "set_velocity", "bodies": ["c", "b"], "angular_velocity": [0, 0, 1]},
        {"time": 3.0, "kind": "remove", "bodies": ["floor"]},
    ], world={"duration": 3.0}))
    assert all(isinstance(e, EventSpec) for e in scene.events)
    assert [(e.time, e.kind) for e in scene.events] == [
        (0.0, "impulse"), (0.5, "set_velocity"), (1.0, "solver"), (1.0, "set_velocity"), (1.0, "solver"),
        (2.0, "iterations"), (3.0, "remove")]  # ties keep file order
    impulse, spin, colored, push, jacobi, iters, remove = scene.events
    assert impulse.bodies == [1] and np.allclose(impulse.impulse, [0, 0, 5]) and np.allclose(impulse.point, [2, 0, 1])
    assert spin.bodies == [2, 1] and spin.linear_velocity is None and np.allclose(spin.angular_velocity, [0, 0, 1])
    assert push.bodies == [0] and np.allclose(push.linear_velocity, [1, 2, 3]) and push.angular_velocity is None
    assert (colored.solver, colored.iterations, colored.options) == ("pgs-colored", 20, {"shuffle": True, "seed": 4})
    assert (jacobi.solver, jacobi.iterations, jacobi.options) == ("jacobi", None, {"relaxation": 0.5})
    assert iters.iterations == 40 and iters.solver is None
    assert remove.bodies == [3]  # a static body may be removed
    assert impulse.point is not None and spin.impulse is None and push.new_bodies == []


def test_event_kinds_are_the_documented_ones():
    assert EVENT_KINDS == ("drop", "set_velocity", "impulse", "remove", "solver", "iterations", "gravity", "effects",
                           "fracture", "formulation")
    assert {"wall", "rain"} <= set(GENERATOR_KINDS)


def test_drop_creates_seeded_rain_bodies_with_velocity():
    drop = _drop(0.5, name="p", count=5, linear_velocity=[0, 0, -3], angular_velocity=[1, 0, 0],
                 shapes=["box", "sphere"], half_extents=_DROP, half_extent_range=[0.1, 0.2], mass=2.0,
                 friction=0.3, restitution=0.2)
    scene = _load(_scene([drop]))
    (event,) = scene.events
    assert event.kind == "drop" and event.bodies == [] and len(scene.bodies) == 4
    assert [b.name for b in event.new_bodies] == [f"p_{i}" for i in range(5)]
    for body in event.new_bodies:
        assert np.allclose(body.linear_velocity, [0, 0, -3]) and np.allclose(body.angular_velocity, [1, 0, 0])
        assert body.mass == 2.0 and body.friction == 0.3 and body.restitution == 0.2 and not body.static
        assert np.all(body.position >= [0, 0, 20]) and np.all(body.position <= [4, 4, 22])
    # the same keys as a rain generator give the same bodies
    rain = {k: v for k, v in drop.items() if k != "time"}
    rain["kind"] = "rain"
    again = _load({"generate": [rain]}).bodies
    for x, y in zip(event.new_bodies, again):
        assert np.array_equal(x.position, y.position) and np.array_equal(x.orientation, y.orientation)
        assert x.shapes[0].kind == y.shapes[0].kind


# ---------------------------------------------------------------------------- resolving references
def test_references_resolve_across_drops_and_removals():
    scene = _load(_scene([
        _drop(0.5, name="d", count=2),                                        # d_0 = 4, d_1 = 5
        {"time": 0.7, "kind": "remove", "bodies": [0, "d_0"]},               # a and d_0 leave
        {"time": 0.8, "kind": "set_velocity", "bodies": ["d_1", "b", 1],     # index 1 is c now
         "linear_velocity": [1, 0, 0]},
        _drop(0.9, name="e", count=1, z=30.0),                                # e_0 appended: index 4
        {"time": 1.0, "kind": "impulse", "bodies": ["e_0", "c"], "impulse": [1, 0, 0]},
        {"time": 1.1, "kind": "remove", "bodies": [3]},                       # d_1 leaves; e_0 -> 3
        {"time": 1.2, "kind": "set_velocity", "bodies": [3], "angular_velocity": [0, 0, 1]},
    ]))
    by_kind = [(e.time, e.kind, e.bodies) for e in scene.events]
    assert by_kind == [
        (0.5, "drop", []),
        (0.7, "remove", [0, 4]),
        (0.8, "set_velocity", [3, 0, 1]),   # body list [b, c, floor, d_1]
        (0.9, "drop", []),
        (1.0, "impulse", [4, 1]),           # body list [b, c, floor, d_1, e_0]
        (1.1, "remove", [3]),
        (1.2, "set_velocity", [3]),         # body list [b, c, floor, e_0]: index 3 is e_0, dynamic
    ]


def test_references_follow_time_order_not_file_order():
    scene = _load(_scene([
        {"time": 2.0, "kind": "set_velocity", "bodies": ["late_0"], "linear_velocity": [0, 0, 1]},
        _drop(1.0, name="late", count=1),
    ]))
    assert [e.kind for e in scene.events] == ["drop", "set_velocity"]
    assert scene.events[1].bodies == [4]


def test_same_time_drop_then_reference_in_file_order():
    scene = _load(_scene([
        _drop(1.0, name="x", count=1),
        {"time": 1.0, "kind": "impulse", "bodies": ["x_0"], "impulse": [0, 0, 1]},
    ]))
    assert scene.events[1].bodies == [4]


def test_events_are_deterministic():
    data = _scene([_drop(0.5, name="d", count=6, shapes=["box", "capsule", "hull"], half_extents=_DROP,
                         half_extent_range=[0.1, 0.3])])
    a, b = _load(data), _load(data)
    for x, y in zip(a.events[0].new_bodies, b.events[0].new_bodies):
        assert np.array_equal(x.position, y.position) and np.array_equal(x.orientation, y.orientation)
        assert np.array_equal(x.inertia, y.inertia)


# ---------------------------------------------------------------------------- bad events
BAD_EVENTS = [
    # (id, events, top-level extras, entry, fragment)
    ("before-zero", [{"time": -0.1, "kind": "iterations", "iterations": 5}], {}, "event[0].time", "must be >= 0"),
    ("after-duration", [{"time": 4.0, "kind": "iterations", "iterations": 5}], {"world": {"duration": 3.0}},
     "event[0].time", "after the scene's duration 3 s"),
    ("nan-time", [{"time": math.nan, "kind": "iterations", "iterations": 5}], {}, "event[0].time", "finite"),
    ("inf-time", [{"time": math.inf, "kind": "iterations", "iterations": 5}], {}, "event[0].time", "finite"),
    ("missing-time", [{"kind": "iterations", "iterations": 5}], {}, "event[0].time", "missing required key 'time'"),
    ("unknown-kind", [{"time": 1.0, "kind": "explode"}], {}, "event[0].kind",
     "unknown event kind 'explode'; expected one of: drop, set_velocity, impulse, remove, solver, iterations, "
     "gravity, effects, fracture"),
    ("nan-gravity", [{"time": 1.0, "kind": "gravity", "gravity": [0.0, math.nan, -9.81]}], {}, "event[0].gravity",
     "finite"),
    ("short-gravity", [{"time": 1.0, "kind": "gravity", "gravity": [0.0, -9.81]}], {}, "event[0].gravity", "3"),
    ("unknown-effect", [{"time": 1.0, "kind": "effects", "effects": ["friction", "levitation"]}], {},
     "event[0].effects[1]", "levitation"),
    ("missing-kind", [{"time": 1.0}], {}, "event[0].kind", "missing required key 'kind'"),
    ("unknown-key", [{"time": 1.0, "kind": "remove", "bodies": ["a"], "force": 3}], {}, "event[0].force",
     "unknown key 'force' for a 'remove' event; allowed keys: bodies, kind, time"),
    ("key-of-other-kind", [{"time": 1.0, "kind": "impulse", "bodies": ["a"], "impulse": [1, 0, 0],
                            "linear_velocity": [1, 0, 0]}], {}, "event[0].linear_velocity", "unknown key"),
    ("missing-body-name", [{"time": 1.0, "kind": "remove", "bodies": ["zz"]}], {}, "event[0].bodies[0]",
     "no body named 'zz'"),
    ("missing-body-index", [{"time": 1.0, "kind": "remove", "bodies": [4]}], {}, "event[0].bodies[0]",
     "body index 4 does not exist at t = 1 s: the body list then has 4 bodies (indices 0..3)"),
    ("index-gone-after-remove", [{"time": 1.0, "kind": "remove", "bodies": [0]},
                                 {"time": 2.0, "kind": "remove", "bodies": [3]}], {}, "event[1].bodies[0]",
     "body index 3 does not exist at t = 2 s"),
    ("name-removed", [{"time": 1.0, "kind": "remove", "bodies": ["b"]},
                      {"time": 2.0, "kind": "impulse", "bodies": ["b"], "impulse": [1, 0, 0]}], {},
     "event[1].bodies[0]", "body 'b' does not exist at t = 2 s: event[0] removed it at t = 1 s"),
    ("name-not-yet-dropped", [{"time": 1.0, "kind": "remove", "bodies": ["d_0"]}, _drop(2.0, name="d")], {},
     "event[0].bodies[0]", "body 'd_0' does not exist yet at t = 1 s: event[1] drops it at t = 2 s"),
    ("mesh-is-not-a-body", [{"time": 1.0, "kind": "remove", "bodies": ["ground"]}], {}, "event[0].bodies[0]",
     "'ground' is a static mesh, not a body"),
    ("static-set-velocity", [{"time": 1.0, "kind": "set_velocity", "bodies": ["a", "floor"],
                              "linear_velocity": [1, 0, 0]}], {}, "event[0].bodies[1]",
     "body 'floor' is static: static bodies cannot be pushed"),
    ("static-impulse-by-index", [{"time": 1.0, "kind": "impulse", "bodies": [3], "impulse": [1, 0, 0]}], {},
     "event[0].bodies[0]", "body index 3 ('floor') is static: static bodies cannot be pushed"),
    ("duplicate-reference", [{"time": 1.0, "kind": "remove", "bodies": ["b", 1]}], {}, "event[0].bodies[1]",
     "body index 1 ('b') is listed twice (also as bodies[0])"),
    ("empty-bodies", [{"time": 1.0, "kind": "remove", "bodies": []}], {}, "event[0].bodies",
     "non-empty list of body names or indices"),
    ("bool-reference", [{"time": 1.0, "kind": "remove", "bodies": [True]}], {}, "event[0].bodies[0]",
     "expected a body name (string) or index (integer >= 0)"),
    ("float-reference", [{"time": 1.0, "kind": "remove", "bodies": [1.0]}], {}, "event[0].bodies[0]",
     "expected a body name (string) or index"),
    ("negative-index", [{"time": 1.0, "kind": "remove", "bodies": [-1]}], {}, "event[0].bodies[0]", "must be >= 0"),
    ("bodies-not-a-list", [{"time": 1.0, "kind": "remove", "bodies": "a"}], {}, "event[0].bodies",
     "expected a list"),
    ("set-velocity-nothing", [{"time": 1.0, "kind": "set_velocity", "bodies": ["a"]}], {},
     "event[0].linear_velocity", "needs 'linear_velocity', 'angular_velocity' or both"),
    ("impulse-missing", [{"time": 1.0, "kind": "impulse", "bodies": ["a"]}], {}, "event[0].impulse",
     "missing required key 'impulse'"),
    ("impulse-nan", [{"time": 1.0, "kind": "impulse", "bodies": ["a"], "impulse": [math.nan, 0, 0]}], {},
     "event[0].impulse", "finite"),
    ("point-length", [{"time": 1.0, "kind": "impulse", "bodies": ["a"], "impulse": [1, 0, 0], "point": [0, 0]}],
     {}, "event[0].point", "expected a list of 3 numbers"),
    ("solver-unknown", [{"time": 1.0, "kind": "solver", "name": "sor"}], {}, "event[0].name", "unknown solver 'sor'"),
    ("solver-option-not-taken", [{"time": 1.0, "kind": "solver", "name": "pgs", "relaxation": 0.5}], {},
     "event[0].relaxation", "option 'relaxation' does not apply to solver 'pgs'"),
    ("solver-option-range", [{"time": 1.0, "kind": "solver", "name": "jacobi", "relaxation": 2.0}], {},
     "event[0].relaxation", "must be < 2.0"),
    ("solver-option-type", [{"time": 1.0, "kind": "solver", "name": "pgs-colored", "shuffle": 1}], {},
     "event[0].shuffle", "expected true or false"),
    ("solver-missing-name", [{"time": 1.0, "kind": "solver", "iterations": 3}], {}, "event[0].name",
     "missing required key 'name'"),
    ("iterations-zero", [{"time": 1.0, "kind": "iterations", "iterations": 0}], {}, "event[0].iterations",
     "must be >= 1"),
    ("iterations-float", [{"time": 1.0, "kind": "iterations", "iterations": 2.5}], {}, "event[0].iterations",
     "expected an integer"),
    ("drop-name-clash", [_drop(1.0, name="a", count=1), _drop(2.0, name="a", count=1)], {"body": [_box(0, "a_0")]},
     "event[0].name", "duplicate name 'a_0' (already used by body[0])"),
    ("drop-region-too-small", [_drop(1.0, count=500)], {}, "event[0].region", "region too small"),
    ("drop-seed-missing", [{"time": 1.0, "kind": "drop", "count": 1, "region": [[0, 0, 0], [1, 1, 1]],
                            "half_extents": 0.1}], {}, "event[0].seed", "missing required key 'seed'"),
    ("drop-velocity-nan", [_drop(1.0, linear_velocity=[0, math.inf, 0])], {}, "event[0].linear_velocity", "finite"),
    ("events-not-tables", [3], {}, "event[0]", "expected a table"),
]


@pytest.mark.parametrize("events,extra,entry,fragment", [c[1:] for c in BAD_EVENTS], ids=[c[0] for c in BAD_EVENTS])
def test_bad_event_raises_scene_error_naming_source_entry_problem(events, extra, entry, fragment):
    data = _scene(events)
    data.update(copy.deepcopy(extra))
    with pytest.raises(SceneError) as info:
        _load(data)
    err = info.value
    assert err.source == SOURCE and SOURCE in str(err)
    assert err.entry == entry and f"entry {entry}:" in str(err), str(err)
    assert fragment in str(err), str(err)


def test_bad_event_in_a_file_names_the_file(tmp_path):
    path = tmp_path / "timeline.toml"
    path.write_text('[world]\nduration = 2.0\n\n[[body]]\nname = "a"\nshape = "sphere"\nradius = 0.5\n'
                    'position = [0, 0, 1]\n\n[[event]]\ntime = 2.5\nkind = "remove"\nbodies = ["a"]\n')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.source == str(path) and str(path) in str(info.value)
    assert info.value.entry == "event[0].time" and "after the scene's duration" in str(info.value)


def test_event_at_exactly_the_duration_is_allowed():
    scene = _load(_scene([{"time": 3.0, "kind": "remove", "bodies": ["a"]}], world={"duration": 3.0}))
    assert scene.events[0].bodies == [0]


# ---------------------------------------------------------------------------- wall generator
def _wall(**keys) -> list:
    entry = {"kind": "wall", "rows": 4, "columns": 5, "half_extents": [0.5, 0.25, 0.25], "position": [0, 0, 0.25]}
    entry.update(keys)
    return _load({"generate": [_clean(entry)]}).bodies


def test_wall_counts_positions_and_touching():
    bodies = _wall(name="w")
    pos = np.array([b.position for b in bodies])
    assert len(bodies) == 20 == generators.wall_count(4, 5)
    assert [b.name for b in bodies[:2]] == ["w_0", "w_1"]
    assert np.allclose(pos[:5, 0], [-2, -1, 0, 1, 2]) and np.allclose(pos[:, 1], 0)  # bottom row centred
    assert np.allclose(np.unique(pos[:, 2]), [0.25, 0.75, 1.25, 1.75])
    assert np.allclose(pos[5:10, 0], pos[:5, 0])  # stack bond: columns aligned
    assert all(np.allclose(b.shapes[0].half_extents, [0.5, 0.25, 0.25]) for b in bodies)
    assert all(np.allclose(b.orientation, [1, 0, 0, 0]) for b in bodies)
    assert bodies[0].mass == pytest.approx(1000.0 * 0.25)
    _assert_disjoint(bodies)


def test_wall_running_bond_direction_y_and_gap():
    bodies = _wall(rows=3, columns=4, half_extents=_DROP, size=[1.0, 0.5, 0.6], position=[3, 1, 0.3],
                   bond="running", direction="y", gap=0.1)
    pos = np.array([b.position for b in bodies])
    assert len(bodies) == 12
    assert np.allclose(pos[:, 0], 3)  # the wall runs along y at x = 3
    pitch = 1.1
    assert np.allclose(pos[:4, 1], 1 + (np.arange(4) - 1.5) * pitch)
    assert np.allclose(pos[4:8, 1], pos[:4, 1] + pitch / 2)  # odd row: half a brick along +y
    assert np.allclose(pos[8:, 1], pos[:4, 1])
    assert np.allclose(pos[::4, 2], [0.3, 1.0, 1.7])  # rise 0.6 + gap 0.1
    assert np.allclose(bodies[0].shapes[0].half_extents, [0.25, 0.5, 0.3])  # length along y, thickness along x
    _assert_disjoint(bodies)


@pytest.mark.parametrize("keys,entry,fragment", [
    ({"rows": 0}, "generate[0].rows", "must be >= 1"),
    ({"columns": 1.5}, "generate[0].columns", "expected an integer"),
    ({"direction": "z"}, "generate[0].direction", "unknown wall direction 'z'; expected one of: x, y"),
    ({"bond": "flemish"}, "generate[0].bond", "unknown wall bond 'flemish'; expected one of: stack, running"),
    ({"gap": -0.1}, "generate[0].gap", "must be >= 0"),
    ({"size": 1.0}, "generate[0].size", "give either 'half_extents' or 'size', not both"),
    ({"rows": 2**40, "columns": 2**40}, "generate[0].rows", "a scene holds at most"),
    ({"seed": 1}, "generate[0].seed", "unknown key 'seed' for a 'wall' generator"),
])
def test_bad_wall(keys, entry, fragment):
    entry_dict = {"kind": "wall", "rows": 2, "columns": 2, "half_extents": 0.5, "position": [0, 0, 0.5], **keys}
    with pytest.raises(SceneError) as info:
        _load({"generate": [entry_dict]})
    assert info.value.entry == entry and fragment in str(info.value), str(info.value)


# ---------------------------------------------------------------------------- rain generator
def _rain(**keys) -> dict:
    entry = {"kind": "rain", "count": 200, "region": [[-3, -3, 1], [3, 3, 9]],
             "shapes": ["box", "sphere", "capsule", "hull"], "half_extent_range": [0.1, 0.3], "seed": 5}
    entry.update(keys)
    return _clean(entry)


def test_rain_count_region_and_no_overlap():
    bodies = _load({"generate": [_rain(name="r")]}).bodies
    assert len(bodies) == 200 and bodies[-1].name == "r_199"
    assert {b.shapes[0].kind for b in bodies} == {"box", "sphere", "capsule", "hull"}
    low, high = _aabbs(bodies)
    assert np.all(low >= np.array([-3, -3, 1]) - 1e-9) and np.all(high <= np.array([3, 3, 9]) + 1e-9)
    _assert_disjoint(bodies)
    quats = np.array([b.orientation for b in bodies])
    assert len(np.unique(np.round(quats, 6), axis=0)) == 200  # random orientations by default
    assert all(np.allclose(b.linear_velocity, 0) and np.allclose(b.angular_velocity, 0) for b in bodies)


def test_rain_is_seeded():
    a = _load({"generate": [_rain()]}).bodies
    b = _load({"generate": [_rain()]}).bodies
    c = _load({"generate": [_rain(seed=6)]}).bodies
    assert all(np.array_equal(x.position, y.position) and np.array_equal(x.orientation, y.orientation)
               for x, y in zip(a, b))
    assert not all(np.array_equal(x.position, y.position) for x, y in zip(a, c))


def test_rain_fills_a_tight_region_without_overlap():
    # 64 unit cubes, identity orientation, in a region of exactly 4 x 4 x 4 cells: every cell used
    bodies = _load({"generate": [_rain(count=64, region=[[0, 0, 0], [4, 4, 4]], shapes=["box"], half_extents=0.5,
                                       half_extent_range=_DROP, orientation="identity")]}).bodies
    pos = np.array([b.position for b in bodies])
    assert np.allclose(np.sort(pos[:, 0].reshape(-1)), np.sort(np.tile(np.arange(4) + 0.5, 16)))
    _assert_disjoint(bodies)


def test_rain_velocities_and_fixed_orientation():
    q = [0.9238795, 0.0, 0.0, 0.3826834]
    bodies = _load({"generate": [_rain(count=10, shapes=["box"], half_extent_range=_DROP, half_extents=[0.3, 0.2, 0.1],
                                       orientation=q, linear_velocity=[5, 0, 0], angular_velocity=[0, 0, 2])]}).bodies
    assert all(np.allclose(b.orientation, q, atol=1e-6) for b in bodies)
    assert all(np.allclose(b.linear_velocity, [5, 0, 0]) and np.allclose(b.angular_velocity, [0, 0, 2])
               for b in bodies)


@pytest.mark.parametrize("keys,entry,fragment", [
    ({"count": 500, "region": [[0, 0, 0], [3, 3, 3]]}, "generate[0].region", "region too small: 500 bodies"),
    ({"region": [[0, 0, 0], [0, 1, 1]]}, "generate[0].region", "low < high on every axis"),
    ({"region": [[0, 0, 0]]}, "generate[0].region", "two corners"),
    ({"region": [[0, 0, 0], [1, 1]]}, "generate[0].region[1]", "expected a point"),
    ({"seed": _DROP}, "generate[0].seed", "missing required key 'seed'"),
    ({"count": 0}, "generate[0].count", "must be >= 1"),
    ({"shapes": ["cone"]}, "generate[0].shapes[0]", "unknown rain shape 'cone'"),
    ({"orientation": "spin"}, "generate[0].orientation", "unknown rain orientation 'spin'"),
    ({"half_extent_range": [0.3, 0.1]}, "generate[0].half_extent_range", "low <= high"),
    ({"spacing": 1.0}, "generate[0].spacing", "unknown key 'spacing' for a 'rain' generator"),
])
def test_bad_rain(keys, entry, fragment):
    data = _rain(**keys)
    with pytest.raises(SceneError) as info:
        _load({"generate": [data]})
    assert info.value.entry == entry and fragment in str(info.value), str(info.value)


# ---------------------------------------------------------------------------- shipped scenes
def test_dominoes_scene_pushes_the_first_domino():
    scene = load_scene(SCENES / "dominoes.toml")
    assert len(scene.bodies) == 15
    pos = np.array([b.position for b in scene.bodies])
    assert np.allclose(np.diff(pos[:, 0]), 1.0) and np.allclose(pos[:, 2], 0.5)
    assert np.allclose(scene.bodies[0].shapes[0].half_extents, [0.125, 0.25, 0.5])
    (event,) = scene.events
    assert event.kind == "impulse" and event.time == 0.5 and event.bodies == [0]
    assert np.allclose(event.impulse, [0.2, 0, 0]) and np.allclose(event.point, [pos[0, 0], 0, 1.0])
    _assert_disjoint(scene.bodies)


def test_scripted_drop_300_scene():
    scene = load_scene(SCENES / "scripted_drop_300.toml")
    assert len(scene.bodies) == 300 and scene.world.duration == 3.0
    (event,) = scene.events
    assert event.kind == "drop" and event.time == 1.0 and len(event.new_bodies) == 20
    pile_top = max(b.position[2] + 0.5 for b in scene.bodies)
    low, _ = _aabbs(event.new_bodies)
    assert low[:, 2].min() > pile_top + 1.0  # the drop starts clear of the pile
    _assert_disjoint(scene.bodies + event.new_bodies)
    assert np.allclose(min(b.position[2] for b in scene.bodies), 0.5)  # resting on the ground


def test_destruction_arena_refers_to_a_dropped_body_by_name():
    scene = load_scene(SCENES / "destruction_arena.toml")
    drops = [e for e in scene.events if e.kind == "drop"]
    assert [len(e.new_bodies) for e in drops] == [1, 3, 4]
    assert all(np.linalg.norm(b.linear_velocity) > 20 for e in drops for b in e.new_bodies)
    (throw,) = [e for e in scene.events if e.kind == "set_velocity"]
    assert throw.bodies == [len(scene.bodies)]  # ball_0, the first body appended by the first drop
    _assert_disjoint(scene.bodies + [b for e in drops for b in e.new_bodies])


def test_confined_pile_starts_inside_the_container():
    scene = load_scene(SCENES / "confined_pile.toml")
    walls = [b for b in scene.bodies if b.static]
    pile = [b for b in scene.bodies if not b.static] + [b for e in scene.events for b in e.new_bodies]
    assert len(walls) == 4 and len(pile) == 600
    low, high = _aabbs(pile)
    assert np.all(low[:, :2] >= -2.0) and np.all(high[:, :2] <= 2.0) and np.all(low[:, 2] >= 0.0)
    _assert_disjoint([b for b in scene.bodies if not b.static])
    _assert_disjoint(scene.bodies)  # the walls touch each other only at faces


def test_mass_ratio_stacks_ratios():
    scene = load_scene(SCENES / "mass_ratio_stacks.toml")
    assert len(scene.bodies) == 12
    for k, ratio in enumerate((10.0, 100.0, 1000.0)):
        column = scene.bodies[4 * k: 4 * k + 4]
        masses = np.array([b.mass for b in column])
        assert masses[0] == pytest.approx(1.0) and masses[-1] / masses[0] == pytest.approx(ratio)
        assert np.all(np.diff(masses) > 0)  # heavy on light
        assert np.allclose([b.position[2] for b in column], [0.5, 1.5, 2.5, 3.5])
    ref = anchor_scene("massratio1000_heavy_on_light")["bodies"]
    assert [b.mass for b in scene.bodies[8:]] == pytest.approx([b["mass"] for b in ref])


def test_spinning_bodies_never_touch():
    scene = load_scene(SCENES / "spinning_bodies.toml")
    assert np.allclose(scene.world.gravity, 0) and not scene.planes and not scene.meshes
    assert all(np.linalg.norm(b.angular_velocity) > 0 for b in scene.bodies)
    # bounding spheres about each centre of mass stay disjoint whatever the rotation
    radius = []
    for body in scene.bodies:
        r = 0.0
        for shape in body.shapes:
            if shape.kind == "box":
                r = max(r, np.linalg.norm(shape.local_position) + np.linalg.norm(shape.half_extents))
            else:
                r = max(r, np.linalg.norm(shape.local_position) + shape.radius + shape.half_height)
        radius.append(r)
    pos = np.array([b.position for b in scene.bodies])
    for i in range(len(pos)):
        for j in range(i + 1, len(pos)):
            assert np.linalg.norm(pos[i] - pos[j]) > radius[i] + radius[j]


def test_headline_pile_scales_to_the_anchor_layout():
    scene = load_scene(SCENES / "headline_pile.toml")
    assert len(scene.bodies) == 1000 and not scene.planes
    assert all(b.mass == 8.0 and np.allclose(b.shapes[0].half_extents, 0.1) for b in scene.bodies)
    (mesh,) = scene.meshes
    assert len(mesh.vertices) == 65 * 65 and len(mesh.triangles) == 8192
    # the two keys the file's comment names give the anchors' 5000-box layout
    data = tomllib.loads((SCENES / "headline_pile.toml").read_text())
    data["generate"][0]["counts"] = [25, 25, 8]
    data["generate"][0]["origin"] = [-4.2, -4.2, 0.6]
    big = scene_from_dict(data, source="headline_5000", base_dir=SCENES)
    assert len(big.bodies) == 5000
    ref = anchor_scene("heightfield_pile")
    assert np.allclose([b.position for b in big.bodies], [b["pos"] for b in ref["bodies"]], atol=1e-6)
    assert np.allclose(mesh.vertices, ref["static"][0]["vertices"], atol=1e-6)


@pytest.mark.parametrize("name", ["leaning_planks", "friction_arch"])
def test_thin_and_hull_scenes_start_on_the_ground(name):
    scene = load_scene(SCENES / f"{name}.toml")
    lowest = min(_aabbs([b])[0][0, 2] for b in scene.bodies)
    assert lowest == pytest.approx(0.0, abs=1e-9)
    assert len(scene.bodies) == {"leaning_planks": 40, "friction_arch": 21}[name]


def test_gravity_and_effects_events_load_and_apply():
    from sandbox import World

    scene = _load(_scene([{"time": 0.5, "kind": "gravity", "gravity": [0.0, 0.0, 0.0]},
                          {"time": 0.5, "kind": "effects", "effects": ["restitution"]}]))
    gravity, effects = scene.events
    assert gravity.kind == "gravity" and np.array_equal(gravity.gravity, [0.0, 0.0, 0.0])
    assert effects.kind == "effects" and effects.effects == ("restitution",)
    world = World(scene, arch=TEST_ARCH)
    world.step(31)  # the events apply at step 30
    assert not np.any(world.gravity) and world.effects == ("restitution",) and not world.friction
    world.set_velocity([1], linear=[0.0, 0.0, 1.0])  # box b: clear of the height field
    world.step(10)  # weightless: the box keeps rising at 1 m/s (with gravity it would be falling at 0.6)
    assert abs(world.state()["linear_velocity"][1, 2] - 1.0) < 1e-4
