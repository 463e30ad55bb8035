"""Bad scenes fail with one SceneError naming the source, the entry and the problem, never anything else."""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sandbox.errors import SceneError
from sandbox.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
SOURCE = "bad_scene.toml"

BOX = {"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [0, 0, 0.5]}
CUBE_CORNERS = [[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]


def _with(section: str, **entry) -> dict:
    return {section: [entry]}


def _body(**changes) -> dict:
    body = dict(BOX)
    for k, v in changes.items():
        if v is _DROP:
            body.pop(k)
        else:
            body[k] = v
    return {"body": [body]}


_DROP = object()
_SPHERE_POINTS = [[np.cos(a) * np.sin(b), np.sin(a) * np.sin(b), np.cos(b)]
                  for a in np.linspace(0, 2 * np.pi, 10, endpoint=False) for b in np.linspace(0.2, 2.9, 10)]

# (id, scene dict, expected entry, fragment of the problem)
CASES = [
    # unknown keys, listing the allowed ones
    ("unknown-top-key", {"bodies": []}, "bodies", "allowed keys: body, description"),
    ("unknown-body-key", _body(radius=1.0), "body[0].radius", "allowed keys:"),
    ("unknown-world-key", {"world": {"gravty": [0, 0, -9.81]}}, "world.gravty", "allowed keys: baumgarte, contact_hertz, dt, duration, formulation, gravity, speculative_contacts, "
     "speculative_speed, substeps"),
    ("unknown-solver-key", {"solver": {"omega": 1.0}}, "solver.omega", "unknown key 'omega'"),
    ("static-mass-not-allowed", _with("static", **BOX, mass=3.0), "static[0].mass", "unknown key 'mass'"),
    ("compound-part-friction", _body(shape="compound", half_extents=_DROP,
                                     parts=[{"shape": "sphere", "radius": 1, "friction": 0.2}]),
     "body[0].parts[0].friction", "unknown key"),
    # wrong types
    ("half-extents-string", _body(half_extents="big"), "body[0].half_extents", "expected a list"),
    ("dt-string", {"world": {"dt": "fast"}}, "world.dt", "expected a number"),
    ("substeps-float", {"world": {"substeps": 1.5}}, "world.substeps", "expected an integer"),
    ("radius-bool", {"body": [{"shape": "sphere", "radius": True, "position": [0, 0, 0]}]}, "body[0].radius",
     "expected a number"),
    ("position-length", _body(position=[0, 0]), "body[0].position", "expected a list of 3 numbers"),
    ("position-of-strings", _body(position=["a", 0, 0]), "body[0].position", "expected a number"),
    ("static-flag-string", _body(static="yes"), "body[0].static", "expected true or false"),
    ("name-number", _body(name=3), "body[0].name", "expected a string"),
    ("body-not-table", {"body": [3]}, "body[0]", "expected a table"),
    ("body-not-list", {"body": dict(BOX)}, "body", "expected a list"),
    ("world-not-table", {"world": [1, 2]}, "world", "expected a table"),
    ("huge-int", _body(position=[10**400, 0, 0]), "body[0].position", "too large"),
    ("shuffle-int", {"solver": {"name": "pgs-colored", "shuffle": 1}}, "solver.shuffle", "expected true or false"),
    # missing required keys
    ("box-no-half-extents", _body(half_extents=_DROP), "body[0].half_extents", "missing required key 'half_extents'"),
    ("body-no-shape", _body(shape=_DROP), "body[0].shape", "missing required key 'shape'"),
    ("body-no-position", _body(position=_DROP), "body[0].position", "missing required key 'position'"),
    ("capsule-no-half-height", {"body": [{"shape": "capsule", "radius": 1, "position": [0, 0, 0]}]},
     "body[0].half_height", "missing required key"),
    ("hull-no-source", {"body": [{"shape": "hull", "position": [0, 0, 0]}]}, "body[0].vertices", "one of"),
    ("plane-no-normal", _with("static", shape="plane"), "static[0].normal", "missing required key 'normal'"),
    ("stack-no-count", _with("generate", kind="stack", half_extents=[1, 1, 1], position=[0, 0, 0]),
     "generate[0].count", "missing required key"),
    ("grid-no-size", _with("generate", kind="grid", counts=[1, 1, 1], spacing=1, origin=[0, 0, 0]),
     "generate[0].half_extents", "one of"),
    # zero / negative sizes, masses, densities, dt
    ("zero-half-extent", _body(half_extents=[0.5, 0, 0.5]), "body[0].half_extents", "> 0"),
    ("negative-radius", {"body": [{"shape": "sphere", "radius": -1, "position": [0, 0, 0]}]}, "body[0].radius", "> 0"),
    ("zero-half-height", {"body": [{"shape": "capsule", "radius": 1, "half_height": 0, "position": [0, 0, 0]}]},
     "body[0].half_height", "> 0"),
    ("negative-mass", _body(mass=-1.0), "body[0].mass", "> 0"),
    ("zero-density", _body(density=0), "body[0].density", "> 0"),
    ("zero-dt", {"world": {"dt": 0}}, "world.dt", "> 0"),
    ("negative-dt", {"world": {"dt": -0.01}}, "world.dt", "> 0"),
    ("zero-substeps", {"world": {"substeps": 0}}, "world.substeps", ">= 1"),
    ("zero-iterations", {"solver": {"iterations": 0}}, "solver.iterations", ">= 1"),
    ("negative-gap", _with("generate", kind="stack", count=2, size=1, position=[0, 0, 0], gap=-0.1),
     "generate[0].gap", ">= 0"),
    ("zero-part-density", _body(shape="compound", half_extents=_DROP,
                                parts=[{"shape": "sphere", "radius": 1, "density": 0}]),
     "body[0].parts[0].density", "> 0"),
    ("zero-hull-scale", {"body": [{"shape": "hull", "vertices": CUBE_CORNERS, "scale": 0, "position": [0, 0, 0]}]},
     "body[0].scale", "> 0"),
    ("zero-heightfield-cells", _with("static", shape="mesh", heightfield={"function": "sines", "amplitude": 1,
                                                                          "size": [1, 1], "cells": [0, 4]}),
     "static[0].heightfield.cells", ">= 1"),
    ("negative-grid-spacing", _with("generate", kind="grid", counts=[2, 2, 2], spacing=-1, origin=[0, 0, 0],
                                    half_extents=0.1), "generate[0].spacing", "> 0"),
    # ranges
    ("relaxation-two", {"solver": {"name": "jacobi", "relaxation": 2.0}}, "solver.relaxation", "< 2.0"),
    ("relaxation-zero", {"solver": {"name": "jacobi", "relaxation": 0}}, "solver.relaxation", "> 0.0"),
    ("option-for-other-solver", {"solver": {"name": "pgs", "shuffle": True}}, "solver.shuffle",
     "option 'shuffle' does not apply to solver 'pgs' (it takes: no options)"),
    ("option-default-solver", {"solver": {"relaxation": 0.5}}, "solver.relaxation", "does not apply to solver 'pgs'"),
    ("restitution-above-one", _body(restitution=1.5), "body[0].restitution", "<= 1.0"),
    ("negative-friction", _body(friction=-0.1), "body[0].friction", ">= 0"),
    ("range-reversed", _with("generate", kind="grid", counts=[1, 1, 1], spacing=1, origin=[0, 0, 0],
                             half_extent_range=[0.5, 0.2], seed=1), "generate[0].half_extent_range", "low <= high"),
    ("count-too-big", _with("generate", kind="stack", count=10**9, size=1, position=[0, 0, 0]),
     "generate[0].count", "at most"),
    ("grid-too-big", _with("generate", kind="grid", counts=[10**4, 10**4, 10**4], spacing=1, origin=[0, 0, 0],
                           half_extents=0.1), "generate[0].counts", "at most"),
    # NaN and inf
    ("nan-position", _body(position=[math.nan, 0, 0]), "body[0].position", "finite"),
    ("inf-gravity", {"world": {"gravity": [0, 0, -math.inf]}}, "world.gravity", "finite"),
    ("nan-friction", _body(friction=math.nan), "body[0].friction", "finite"),
    ("nan-dt", {"world": {"dt": math.nan}}, "world.dt", "finite"),
    ("nan-hull-vertex", {"body": [{"shape": "hull", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, math.inf]],
                                   "position": [0, 0, 0]}]}, "body[0].vertices[3]", "finite"),
    ("overflowing-position", _body(position=[1.5e308, 0, 0], shape="compound", half_extents=_DROP,
                                   parts=[{"shape": "sphere", "radius": 1, "position": [1.5e308, 0, 0]}]),
     "body[0]", "overflow"),
    ("overflowing-mass", _body(half_extents=[1e300, 1e300, 1e300]), "body[0]", "mass properties are not finite"),
    ("overflowing-hull", {"body": [{"shape": "hull", "vertices": [[x * 1e308, y, z] for x, y, z in CUBE_CORNERS],
                                    "position": [0, 0, 0]}]}, "body[0].vertices", "degenerate"),
    # quaternions and normals
    ("zero-quaternion", _body(orientation=[0, 0, 0, 0]), "body[0].orientation", "zero length"),
    ("zero-normal", _with("static", shape="plane", normal=[0, 0, 0]), "static[0].normal", "zero vector"),
    # exclusive keys
    ("density-and-mass", _body(density=1000, mass=1), "body[0].mass", "not both"),
    ("path-and-heightfield", _with("static", shape="mesh", path="x.obj", heightfield={}), "static[0].heightfield",
     "not both"),
    ("size-and-half-extents", _with("generate", kind="stack", count=2, size=1, half_extents=1, position=[0, 0, 0]),
     "generate[0].size", "not both"),
    # unknown kinds
    ("unknown-shape", _body(shape="cone"), "body[0].shape", "unknown shape 'cone'"),
    ("unknown-static-shape", _with("static", shape="wall"), "static[0].shape", "unknown static shape 'wall'"),
    ("unknown-solver", {"solver": {"name": "sor"}}, "solver.name", "unknown solver 'sor'; expected one of: pgs"),
    ("unknown-generator", _with("generate", kind="tower"), "generate[0].kind", "unknown generator kind 'tower'"),
    ("unknown-heightfield", _with("static", shape="mesh", heightfield={"function": "perlin"}),
     "static[0].heightfield.function", "unknown height-field function"),
    ("unknown-layout", _with("generate", kind="pyramid", base=3, size=1, position=[0, 0, 0], layout="4d"),
     "generate[0].layout", "unknown pyramid layout"),
    ("unknown-grid-shape", _with("generate", kind="grid", counts=[1, 1, 1], spacing=1, origin=[0, 0, 0],
                                 half_extents=0.1, shapes=["box", "torus"], seed=0), "generate[0].shapes[1]",
     "unknown grid shape 'torus'"),
    ("nested-compound", _body(shape="compound", half_extents=_DROP, parts=[{"shape": "compound", "parts": []}]),
     "body[0].parts[0].shape", "unknown compound part shape"),
    # duplicate names
    ("duplicate-names", {"body": [dict(BOX, name="a"), dict(BOX, name="a", position=[3, 0, 0])]}, "body[1].name",
     "duplicate name 'a' (already used by body[0])"),
    ("duplicate-generated-name", {"body": [dict(BOX, name="s_1")],
                                  "generate": [{"kind": "stack", "count": 3, "size": 1, "position": [5, 0, 0],
                                                "name": "s"}]}, "generate[0].name", "duplicate name 's_1'"),
    ("duplicate-mesh-name", {"body": [dict(BOX, name="t")],
                             "static": [{"shape": "mesh", "name": "t", "heightfield": {
                                 "function": "sines", "amplitude": 1, "size": [1, 1], "cells": [1, 1]}}]},
     "static[0].name", "duplicate name"),
    ("empty-name", _body(name=""), "body[0].name", "must not be empty"),
    # hulls
    ("flat-hull", {"body": [{"shape": "hull", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
                             "position": [0, 0, 0]}]}, "body[0].vertices", "degenerate"),
    ("coincident-hull", {"body": [{"shape": "hull", "vertices": [[1, 1, 1]] * 5, "position": [0, 0, 0]}]},
     "body[0].vertices", "degenerate"),
    ("hull-three-points", {"body": [{"shape": "hull", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                                     "position": [0, 0, 0]}]}, "body[0].vertices", "at least 4 points"),
    ("hull-too-many-vertices", {"body": [{"shape": "hull", "vertices": _SPHERE_POINTS, "position": [0, 0, 0]}]},
     "body[0].vertices", "at most 64"),
    # semantic
    ("static-body-moving", _body(static=True, linear_velocity=[1, 0, 0]), "body[0].linear_velocity", "cannot move"),
    ("compound-no-parts", _body(shape="compound", half_extents=_DROP, parts=[]), "body[0].parts", "at least one part"),
    ("seed-needed-orientation", _with("generate", kind="grid", counts=[2, 1, 1], spacing=2, origin=[0, 0, 0],
                                      half_extents=0.1, orientation="random"), "generate[0].seed",
     "missing required key 'seed' (orientation = 'random' draws"),
    ("seed-needed-jitter", _with("generate", kind="stack", count=2, size=1, position=[0, 0, 0], jitter=0.1),
     "generate[0].seed", "missing required key 'seed'"),
    ("grid-overlap", _with("generate", kind="grid", counts=[3, 1, 1], spacing=1.0, origin=[0, 0, 0],
                           half_extents=[0.6, 0.1, 0.1]), "generate[0].spacing", "overlap at t=0"),
    ("weights-one-shape", _with("generate", kind="grid", counts=[1, 1, 1], spacing=1, origin=[0, 0, 0],
                                half_extents=0.1, weights=[1.0]), "generate[0].weights", "at least two"),
    ("weights-zero", _with("generate", kind="grid", counts=[1, 1, 1], spacing=1, origin=[0, 0, 0],
                           half_extents=0.1, shapes=["box", "sphere"], weights=[0, 0], seed=1),
     "generate[0].weights", "not all be zero"),
    ("mesh-file-missing", {"body": [{"shape": "hull", "path": "does/not/exist.obj", "position": [0, 0, 0]}]},
     "body[0].path", "mesh file not found"),
    ("mesh-path-directory", _with("static", shape="mesh", path="."), "static[0].path", "not a file"),
    ("mesh-path-nul", _with("static", shape="mesh", path="a\x00b.obj"), "static[0].path", "invalid mesh file path"),
]


@pytest.mark.parametrize("data,entry,fragment", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_scene_raises_scene_error_naming_source_entry_problem(data, entry, fragment):
    with pytest.raises(SceneError) as info:
        scene_from_dict(copy.deepcopy(data), source=SOURCE)
    err = info.value
    message = str(err)
    assert err.source == SOURCE and SOURCE in message
    assert err.entry == entry and f"entry {entry}:" in message
    assert fragment in message, message


def test_top_level_not_a_table():
    with pytest.raises(SceneError, match=r"scene <dict>: expected a table, got a list"):
        scene_from_dict([1, 2])


def test_error_is_a_value_error_too():
    with pytest.raises(ValueError):
        scene_from_dict({"world": {"dt": 0}})


# ---------------------------------------------------------------------------- files
def _write(tmp_path, text, name="scene.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _expect(path, entry, fragment):
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert str(path) in message and info.value.source == str(path)
    assert info.value.entry == entry
    if entry:
        assert entry in message
    assert fragment in message, message
    return info.value


def test_missing_scene_file(tmp_path):
    _expect(tmp_path / "nope.toml", None, "scene file not found")


def test_scene_path_is_directory(tmp_path):
    _expect(tmp_path, None, "is a directory")


def test_toml_syntax_error_has_line_and_column(tmp_path):
    path = _write(tmp_path, "# ok\n[world]\ndt = [1,\nb =\n")
    err = _expect(path, "line 4, column 1", "TOML syntax error")
    assert err.__cause__ is None


def test_toml_duplicate_table_is_syntax_error(tmp_path):
    path = _write(tmp_path, "[world]\ndt = 0.1\n[world]\ndt = 0.2\n")
    _expect(path, "line 3, column 7", "TOML syntax error")


def test_toml_nan_and_inf_literals(tmp_path):
    _expect(_write(tmp_path, "[world]\ndt = nan\n"), "world.dt", "finite")
    _expect(_write(tmp_path, "[world]\ngravity = [0.0, 0.0, -inf]\n", "g.toml"), "world.gravity", "finite")


def test_scene_file_not_utf8(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_bytes(b"description = '\xff\xfe'\n")
    _expect(path, None, "not UTF-8")


def test_mesh_file_missing_relative_to_scene(tmp_path):
    path = _write(tmp_path, "[[static]]\nshape = 'mesh'\npath = 'missing.obj'\n")
    _expect(path, "static[0].path", f"mesh file not found: {tmp_path / 'missing.obj'}")


def test_mesh_file_garbage(tmp_path):
    (tmp_path / "junk.stl").write_bytes(bytes(range(256)) * 3)
    path = _write(tmp_path, "[[body]]\nshape = 'hull'\npath = 'junk.stl'\nposition = [0, 0, 0]\n")
    err = _expect(path, "body[0].path", "junk.stl")
    assert "cannot read mesh file" in str(err) or "contains no triangles" in str(err)


def test_mesh_file_unknown_format(tmp_path):
    (tmp_path / "shape.xyz123").write_text("1 2 3\n")
    path = _write(tmp_path, "[[static]]\nshape = 'mesh'\npath = 'shape.xyz123'\n")
    _expect(path, "static[0].path", "cannot read mesh file")


def test_toml_syntax_error_at_the_end_of_the_file_says_so(tmp_path):
    path = _write(tmp_path, "[world]\ngravity = [0.0, 0.0,\n")
    _expect(path, "end of file (line 2)", "TOML syntax error: Invalid value")


NAN_TETRAHEDRON = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv nan 0.5 0.5\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\nf 2 3 5\n"
BAD_MESH_FILES = {
    "no_faces": ("# nothing\nv 0 0 0\nv 1 0 0\n", "static", "no triangles"),
    "flat_hull": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n", "body", "degenerate"),
    "face_beyond_vertices": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 9\n", "static",
                             "triangle indices out of range"),
    # trimesh's processing drops NaN vertices and their triangles without a word: the file is
    # checked as written, before it is processed
    "nan_vertex_hull": (NAN_TETRAHEDRON, "body", "NaN or inf vertex coordinates"),
    "nan_vertex_static_mesh": (NAN_TETRAHEDRON, "static", "NaN or inf vertex coordinates"),
}


@pytest.mark.parametrize("case", sorted(BAD_MESH_FILES))
def test_a_bad_mesh_file_is_refused_with_the_reason(tmp_path, case):
    content, section, fragment = BAD_MESH_FILES[case]
    (tmp_path / "shape.obj").write_text(content)
    entry = ("[[body]]\nshape = 'hull'\nposition = [0, 0, 0]\n" if section == "body"
             else "[[static]]\nshape = 'mesh'\n")
    _expect(_write(tmp_path, entry + "path = 'shape.obj'\n"), f"{section}[0].path", fragment)


def test_a_seed_beyond_32_bits_is_refused(tmp_path):
    path = _write(tmp_path, "[solver]\nname = 'pgs-colored'\nseed = 1099511627776\n")
    _expect(path, "solver.seed", "2147483647")


# ---------------------------------------------------------------------------- fuzz
BASE = {
    "description": "fuzz base",
    "world": {"gravity": [0.0, 0.0, -9.81], "dt": 0.01, "substeps": 2, "duration": 5.0},
    "solver": {"name": "pgs-colored", "iterations": 5, "shuffle": False, "seed": 1},
    "effects": ["friction", "restitution"],
    "static": [
        {"shape": "plane", "normal": [0.0, 0.0, 1.0], "offset": 0.0, "friction": 0.5, "restitution": 0.0},
        {"shape": "mesh", "name": "hf", "position": [0.0, 0.0, -1.0],
         "heightfield": {"function": "sines", "amplitude": 0.2, "frequency": [1.0, 2.0], "size": [4.0, 4.0],
                         "cells": [4, 4]}},
        {"shape": "mesh", "path": "meshes/icosahedron.obj", "scale": 0.5, "position": [9.0, 9.0, 0.0]},
        {"shape": "capsule", "radius": 0.2, "half_height": 0.3, "position": [5.0, 0.0, 0.2], "name": "post"},
    ],
    "body": [
        {"shape": "box", "half_extents": [0.5, 0.4, 0.3], "position": [0.0, 0.0, 1.0],
         "orientation": [1.0, 0.0, 0.0, 0.0], "linear_velocity": [0.0, 0.0, 0.0], "angular_velocity": [0.0, 0.0, 1.0],
         "density": 500.0, "friction": 0.5, "restitution": 0.1, "name": "b0"},
        {"shape": "sphere", "radius": 0.3, "position": [2.0, 0.0, 1.0], "mass": 3.0},
        {"shape": "hull", "vertices": CUBE_CORNERS, "scale": [1.0, 2.0, 1.0], "position": [4.0, 0.0, 1.0]},
        {"shape": "hull", "path": "meshes/icosahedron.obj", "position": [6.0, 0.0, 1.0], "static": True},
        {"shape": "compound", "position": [8.0, 0.0, 1.0],
         "parts": [{"shape": "box", "half_extents": [0.2, 0.2, 0.2], "position": [0.3, 0.0, 0.0], "density": 800.0},
                   {"shape": "capsule", "radius": 0.1, "half_height": 0.2, "orientation": [0.7, 0.7, 0.0, 0.0]}]},
    ],
    "generate": [
        {"kind": "stack", "count": 3, "half_extents": [0.2, 0.2, 0.2], "position": [0.0, 5.0, 0.2], "gap": 0.01,
         "jitter": 0.01, "seed": 3, "name": "st"},
        {"kind": "pyramid", "base": 3, "size": [0.4, 0.4, 0.4], "position": [0.0, 8.0, 0.2], "layout": "3d"},
        {"kind": "grid", "counts": [2, 2, 2], "spacing": [1.5, 1.5, 1.5], "origin": [-5.0, -5.0, 1.0],
         "shapes": ["box", "sphere", "capsule", "hull"], "weights": [1.0, 1.0, 1.0, 1.0],
         "half_extent_range": [0.2, 0.4], "orientation": "random", "seed": 9, "mass": 2.0},
        {"kind": "wall", "rows": 2, "columns": 3, "half_extents": [0.3, 0.1, 0.1], "position": [0.0, -8.0, 0.1],
         "direction": "y", "bond": "running", "gap": 0.01, "name": "w"},
        {"kind": "rain", "count": 3, "region": [[10.0, 10.0, 1.0], [13.0, 13.0, 4.0]], "shapes": ["box", "sphere"],
         "half_extent_range": [0.1, 0.3], "seed": 2, "linear_velocity": [0.0, 0.0, -1.0]},
    ],
    "event": [
        {"time": 0.5, "kind": "drop", "name": "d", "count": 2, "region": [[-2.0, -2.0, 8.0], [2.0, 2.0, 10.0]],
         "shapes": ["capsule", "hull"], "half_extent_range": [0.1, 0.2], "seed": 3, "density": 500.0},
        {"time": 1.0, "kind": "set_velocity", "bodies": ["b0", 1], "linear_velocity": [1.0, 0.0, 0.0]},
        {"time": 1.0, "kind": "impulse", "bodies": ["d_1"], "impulse": [0.0, 0.0, 2.0], "point": [0.0, 0.0, 9.0]},
        {"time": 2.0, "kind": "remove", "bodies": ["st_0", 3]},
        {"time": 3.0, "kind": "solver", "name": "jacobi", "iterations": 8, "relaxation": 0.5},
        {"time": 4.0, "kind": "iterations", "iterations": 12},
    ],
}


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, prefix + (i,))


PATHS = [p for p in _paths(BASE) if p]

BAD_VALUES = st.one_of(
    st.sampled_from([0, -1, -0.5, 0.0, 1e308, -1e308, 10**400, 2**63, math.nan, math.inf, -math.inf, True, False,
                     None, "", "x", "box", [], [0], [0, 0], [math.nan, 0, 0], [0, 0, 0], [0, 0, 0, 0], [[0, 0, 0]],
                     {}, {"shape": "box"}, [1, 2, 3, 4, 5], ["a", "b", "c"]]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-5, max_value=40),
    st.text(max_size=6),
    st.lists(st.one_of(st.floats(), st.integers(-3, 3), st.text(max_size=2)), max_size=5),
    st.dictionaries(st.text(max_size=4), st.integers(-2, 2), max_size=2),
)


def _mutate(data, path, action, value):
    value = copy.deepcopy(value)  # never share a drawn list between mutations or examples
    node = data
    for key in path[:-1]:
        node = node[key]
    last = path[-1]
    if action == "delete":
        del node[last]
    elif action == "add_key" and isinstance(node[last], dict):
        node[last]["zz_unknown"] = value
    else:
        node[last] = value


def _assert_clean(data):
    try:
        scene = scene_from_dict(data, source="fuzz.toml", base_dir=SCENES)
    except SceneError as err:
        assert err.source == "fuzz.toml" and "fuzz.toml" in str(err)
        return None
    for body in scene.bodies:  # whatever loads is finite and positive
        assert np.all(np.isfinite(body.position)) and body.mass > 0 and np.all(np.isfinite(body.inertia))
        assert np.isclose(np.linalg.norm(body.orientation), 1.0)
    return scene


def test_fuzz_base_scene_is_valid():
    scene = _assert_clean(copy.deepcopy(BASE))
    assert scene is not None and len(scene.bodies) == 5 + 3 + 14 + 8 + 6 + 3 + 1
    assert [e.kind for e in scene.events] == ["drop", "set_velocity", "impulse", "remove", "solver", "iterations"]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_fuzz_mutated_scene_raises_only_scene_error(data):
    scene = copy.deepcopy(BASE)
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(scene) if p]
        path = data.draw(st.sampled_from(paths))
        action = data.draw(st.sampled_from(["replace", "replace", "replace", "delete", "add_key"]))
        _mutate(scene, path, action, data.draw(BAD_VALUES))
    _assert_clean(scene)


@settings(max_examples=200, deadline=None)
@given(
    st.recursive(
        st.one_of(st.none(), st.booleans(), st.floats(), st.integers(-3, 3), st.text(max_size=4)),
        lambda children: st.one_of(
            st.lists(children, max_size=4),
            st.dictionaries(st.sampled_from(["body", "static", "generate", "world", "solver", "event", "effects",
                                             "time", "bodies", "shape", "kind", "position", "radius",
                                             "half_extents", "parts", "count", "x"]),
                            children, max_size=4),
        ),
        max_leaves=12,
    )
)
def test_fuzz_arbitrary_structures_raise_only_scene_error(data):
    _assert_clean(data)


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=200))
def test_fuzz_toml_text_raises_only_scene_error(text):
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.toml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        try:
            load_scene(path)
        except SceneError as err:
            assert str(path) in str(err)


def test_the_cli_refuses_a_bad_scene_in_one_line_before_starting_taichi(tmp_path):
    path = _write(tmp_path, "[world]\nbogus = 1\n")
    run = subprocess.run([sys.executable, "-m", "sandbox.cli", "run", str(path), "--steps", "1"],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    lines = (run.stdout + run.stderr).strip().splitlines()
    assert len(lines) == 1 and "entry world.bogus: unknown key 'bogus'" in lines[0], lines


@pytest.mark.parametrize("extra, message", [
    (["--steps", "0"], "argument --steps: must be a whole number >= 1, got 0"),
    (["--iterations", "-2"], "argument --iterations: must be a whole number >= 1, got -2"),
    (["--record", "{tmp}/missing/run.sbrec"], "recording {tmp}/missing/run.sbrec: cannot write it (no folder"),
    (["--report", "{tmp}"], "report {tmp}: cannot write it (it is a folder)"),
])
def test_the_cli_refuses_bad_run_arguments_before_starting_taichi(tmp_path, extra, message):
    """Counts below 1 and output files that cannot be written are refused before the run, not after it
    (``--record`` to a missing folder once simulated every step, then died with a raw traceback)."""
    extra = [arg.format(tmp=tmp_path) for arg in extra]
    run = subprocess.run([sys.executable, "-m", "sandbox.cli", "run", "stack_20", "--steps", "1", *extra],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert message.format(tmp=tmp_path) in run.stderr, run.stderr
    assert "Taichi" not in run.stdout + run.stderr and "Traceback" not in run.stderr
