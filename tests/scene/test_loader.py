"""Scene loading: shipped scenes, generators, terrain, the COM convention, paths, determinism."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from sandbox.scene import Scene, load_scene, scene_from_dict
from sandbox.scene import generators, terrain
from sandbox.scene.hull import MAX_HULL_VERTICES
from sandbox.scene.rotations import quat_to_matrix
from tests.helpers import anchor_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
SCENE_FILES = sorted(SCENES.glob("*.toml"))

TIGHT = 1e-12
"""[m] Generated positions are sums of a few exactly representable numbers."""
JSON_ROUND = 1e-6
"""scenes.json prints 6 decimals (9 for quaternions)."""


def _anchor(name: str) -> dict:
    return anchor_scene(name)


def _plane_floor() -> dict:
    return {"shape": "plane", "normal": [0, 0, 1]}


# ---------------------------------------------------------------------------- shipped scenes
SHIPPED = {"box_on_plane", "stack_20", "pyramid_20", "pile_1000", "mixed_on_terrain", "mass_ratio_stacks",
           "leaning_planks", "friction_arch", "dominoes", "confined_pile", "projectile_wall", "spinning_bodies",
           "destruction_arena", "headline_pile", "scripted_drop_300"}
SCENE_FRICTION = {"leaning_planks": 0.7, "friction_arch": 0.6, "dominoes": 0.6}
"""Scenes of method.md section 2 that call for another Coulomb coefficient than the anchors' 0.5."""
ZERO_GRAVITY = {"spinning_bodies"}
SLEEPING = {"playground", "headline_pile", "destruction_arena", "confined_pile", "scripted_drop_300"}
"""The showcase scenes that call for the sleeping effect; benchmark scenes never do (sleep would hide jitter)."""
MAX_SHIPPED_BODIES = 1500
"""The smoke test runs every shipped scene for 60 steps on a 2-core CPU; bigger scenes document how to scale up."""
FULL_SCALE = {"headline_pile_5000": 5000}
"""The paper's own scene at full scale, shipped as the throughput benchmark (issue 17): its 60-step
smoke run costs ~16 s on the 2-core VM."""


def test_scene_files_are_shipped():
    names = {p.stem for p in SCENE_FILES}
    assert SHIPPED <= names


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.stem)
def test_scene_file_loads_with_conventions(path):
    assert path.read_text().startswith("#"), "every scene file starts with a comment saying what it teaches"
    scene = load_scene(path)
    assert scene.source == str(path)
    assert scene.description
    assert scene.bodies
    assert scene.world.dt == pytest.approx(1.0 / 60.0)
    gravity = [0, 0, 0] if path.stem in ZERO_GRAVITY else [0, 0, -9.81]
    assert np.allclose(scene.world.gravity, gravity)
    friction = SCENE_FRICTION.get(path.stem, 0.5)
    every = list(scene.bodies) + [b for e in scene.events for b in e.new_bodies]
    assert len(every) <= FULL_SCALE.get(path.stem, MAX_SHIPPED_BODIES)
    for body in every:
        assert body.friction == friction and body.restitution == 0.0
        assert np.isclose(np.linalg.norm(body.orientation), 1.0)
        assert body.mass > 0 and np.all(np.isfinite(body.inertia))
        assert np.allclose(body.inertia, body.inertia.T)
        assert np.all(np.linalg.eigvalsh(body.inertia) > 0)
    for plane in scene.planes:
        assert plane.friction == friction and plane.restitution == 0.0
    for mesh in scene.meshes:
        assert mesh.friction == friction and mesh.restitution == 0.0
    assert scene.effects == ("friction", "restitution") + (("sleeping",) if path.stem in SLEEPING else ())
    times = [e.time for e in scene.events]
    assert times == sorted(times)
    if scene.events:
        assert scene.world.duration is not None and times[-1] <= scene.world.duration


def test_box_on_plane_touches_the_ground():
    scene = load_scene(SCENES / "box_on_plane.toml")
    (body,) = scene.bodies
    (plane,) = scene.planes
    assert body.name == "box"
    assert body.mass == pytest.approx(1000.0)
    assert np.allclose(body.position, [0, 0, 0.5])
    assert np.allclose(plane.normal, [0, 0, 1]) and plane.offset == 0.0
    assert np.allclose(body.inertia, np.eye(3) * 1000.0 / 6.0)


def test_stack_20_matches_anchor_stack20():
    anchor = _anchor("stack20")
    scene = load_scene(SCENES / "stack_20.toml")
    assert len(scene.bodies) == 20
    for body, ref in zip(scene.bodies, anchor["bodies"]):
        assert np.allclose(body.position, ref["pos"], atol=TIGHT)
        assert np.allclose(body.shapes[0].half_extents, ref["half_extents"])
        assert np.allclose(body.orientation, ref["quat"])
        assert body.mass == pytest.approx(ref["mass"])
    z = np.array([b.position[2] for b in scene.bodies])
    assert np.allclose(np.diff(z), 1.0, atol=TIGHT)  # touching: 2 * half extent


def test_pyramid_20_matches_anchor_pyramid20_rows_touching():
    anchor = _anchor("pyramid20")
    scene = load_scene(SCENES / "pyramid_20.toml")
    assert len(scene.bodies) == 210
    pos = np.array([b.position for b in scene.bodies])
    assert np.allclose(pos, [b["pos"] for b in anchor["bodies"]], atol=TIGHT)
    assert all(b.mass == pytest.approx(1000.0) for b in scene.bodies)
    start = 0
    for k in range(20):
        row = pos[start : start + 20 - k]
        assert np.allclose(row[:, 2], 0.5 + k, atol=TIGHT)
        assert np.allclose(np.diff(row[:, 0]), 1.0, atol=TIGHT)  # neighbours touch
        assert np.isclose(row[:, 0].mean(), 0.0, atol=TIGHT)  # each row centred on the one below
        assert np.allclose(row[:, 1], 0.0)
        start += 20 - k
    assert start == 210


def test_pile_1000_statistics_match_anchor_pile1000():
    scene = load_scene(SCENES / "pile_1000.toml")
    assert len(scene.bodies) == 1000
    half = np.array([b.shapes[0].half_extents for b in scene.bodies])
    pos = np.array([b.position for b in scene.bodies])
    quat = np.array([b.orientation for b in scene.bodies])
    assert half.min() >= 0.25 and half.max() <= 0.5
    assert np.allclose(half.mean(axis=0), 0.375, atol=0.01)  # uniform on [0.25, 0.5]: mean 0.375, sd/sqrt(1000) ~ 0.0023
    assert np.allclose(pos.min(axis=0), [-8.1, -8.1, 1.0]) and np.allclose(pos.max(axis=0), [8.1, 8.1, 17.2])
    assert len(np.unique(np.round(pos, 9), axis=0)) == 1000
    assert np.allclose(np.linalg.norm(quat, axis=1), 1.0)
    assert abs(np.mean(quat[:, 1:], axis=0)).max() < 0.05  # uniform rotations have zero-mean x, y, z
    masses = np.array([b.mass for b in scene.bodies])
    assert np.allclose(masses, 8000.0 * half.prod(axis=1))
    # with the anchors' seed and draw order the pile is the anchors' pile, to the JSON's rounding
    anchor = _anchor("pile1000")["bodies"]
    assert np.allclose(half, [b["half_extents"] for b in anchor], atol=JSON_ROUND)
    assert np.allclose(pos, [b["pos"] for b in anchor], atol=JSON_ROUND)
    assert np.allclose(quat, [b["quat"] for b in anchor], atol=JSON_ROUND)


def test_mixed_on_terrain_has_every_shape_kind():
    scene = load_scene(SCENES / "mixed_on_terrain.toml")
    kinds = {b.shapes[0].kind for b in scene.bodies if len(b.shapes) == 1}
    assert kinds == {"box", "sphere", "capsule", "hull"}
    assert 200 <= len(scene.bodies) <= 600
    assert any(len(b.shapes) > 1 for b in scene.bodies)
    (mesh,) = scene.meshes
    assert mesh.name == "terrain" and len(mesh.triangles) == 2 * 96 * 96
    (plane,) = scene.planes
    assert plane.offset == -5.0
    byname = {b.name: b for b in scene.bodies if b.name}
    assert len(byname["pebble"].shapes[0].vertices) == MAX_HULL_VERTICES
    assert len(byname["gem"].shapes[0].vertices) == 12
    # bodies start above the terrain (max height 0.4 m)
    for b in scene.bodies:
        assert b.position[2] > 1.0


def test_scene_layer_does_not_import_taichi():
    """Scenes load without starting Taichi: the scene layer (L1) imports only host geometry."""
    code = (
        "import sys, pathlib\n"
        "from sandbox.scene import load_scene\n"
        "for p in sorted(pathlib.Path('scenes').glob('*.toml')): load_scene(p)\n"
        "bad = sorted(m for m in sys.modules if m == 'taichi' or m.startswith('taichi.'))\n"
        "assert not bad, bad[:3]\n"
        "extra = sorted(m for m in sys.modules if m.startswith('sandbox.') and m.split('.')[1] not in "
        "('scene', 'errors', 'polytope', 'settings', 'solvers'))\n"
        "assert not extra, extra\n"
    )
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)


def test_hulls_accepted_by_loader_build_as_polytopes():
    from sandbox import shapes as engine_shapes

    assert engine_shapes.MAX_POLY_VERTS == MAX_HULL_VERTICES
    scene = load_scene(SCENES / "mixed_on_terrain.toml")
    hulls = [s for b in scene.bodies for s in b.shapes if s.kind == "hull"]
    assert len(hulls) > 20
    for s in hulls:
        poly = engine_shapes.hull_polytope(s.vertices)
        assert len(poly.vertices) == len(s.vertices)


def test_loading_is_deterministic():
    a = load_scene(SCENES / "mixed_on_terrain.toml")
    b = load_scene(SCENES / "mixed_on_terrain.toml")
    for x, y in zip(a.bodies, b.bodies):
        assert np.array_equal(x.position, y.position) and np.array_equal(x.orientation, y.orientation)
        assert np.array_equal(x.inertia, y.inertia)
        for sx, sy in zip(x.shapes, y.shapes):
            assert sx.kind == sy.kind
            if sx.kind == "hull":
                assert np.array_equal(sx.vertices, sy.vertices)


# ---------------------------------------------------------------------------- defaults, world, solver
def test_defaults_when_tables_absent():
    scene = scene_from_dict({"body": [{"shape": "sphere", "radius": 0.5, "position": [0, 0, 1]}]})
    assert scene.source == "<dict>"
    assert np.allclose(scene.world.gravity, [0, 0, -9.81]) and scene.world.dt == 1 / 60 and scene.world.substeps == 1
    assert scene.solver.name == "pgs" and scene.solver.iterations == 10 and scene.solver.options == {}
    (body,) = scene.bodies
    assert body.friction == 0.5 and body.restitution == 0.0 and not body.static and body.name is None
    assert body.mass == pytest.approx(1000.0 * 4 / 3 * np.pi * 0.125)
    assert np.allclose(body.orientation, [1, 0, 0, 0]) and np.allclose(body.linear_velocity, 0)


def test_world_and_solver_options():
    scene = scene_from_dict(
        {
            "world": {"gravity": [0, 0, -1.62], "dt": 0.01, "substeps": 4},
            "solver": {"name": "pgs-colored", "iterations": 20, "shuffle": True, "seed": 3},
        }
    )
    assert np.allclose(scene.world.gravity, [0, 0, -1.62]) and scene.world.dt == 0.01 and scene.world.substeps == 4
    assert scene.solver.name == "pgs-colored" and scene.solver.iterations == 20
    assert scene.solver.options == {"shuffle": True, "seed": 3}
    jacobi = scene_from_dict({"solver": {"name": "jacobi", "relaxation": 0.8}}).solver
    assert jacobi.name == "jacobi" and jacobi.iterations == 10 and jacobi.options == {"relaxation": 0.8}


def test_solver_names_and_options_match_the_solver_registry():
    from sandbox.scene.loader import SOLVER_NAMES, SOLVER_OPTIONS
    from sandbox.solvers import SOLVERS

    assert set(SOLVER_NAMES) == set(SOLVERS)
    for name, info in SOLVERS.items():
        assert set(SOLVER_OPTIONS[name]) == set(info.defaults), name


def test_body_fields_are_read():
    scene = scene_from_dict(
        {
            "body": [
                {
                    "shape": "capsule", "radius": 0.2, "half_height": 0.5, "position": [1, 2, 3],
                    "orientation": [2, 0, 0, 0], "linear_velocity": [1, 0, 0], "angular_velocity": [0, 0, 2],
                    "mass": 7.0, "friction": 0.9, "restitution": 0.3, "name": "cap",
                },
                {"shape": "box", "half_extents": [1, 1, 1], "position": [0, 0, 0], "static": True},
            ],
            "static": [{"shape": "sphere", "radius": 1.0, "position": [5, 0, 0], "name": "rock"}],
        }
    )
    cap, box, rock = scene.bodies
    assert np.allclose(cap.orientation, [1, 0, 0, 0])  # normalised
    assert cap.mass == 7.0 and cap.friction == 0.9 and cap.restitution == 0.3 and cap.name == "cap"
    assert np.allclose(cap.linear_velocity, [1, 0, 0]) and np.allclose(cap.angular_velocity, [0, 0, 2])
    assert box.static and rock.static and rock.name == "rock"
    assert np.allclose(rock.position, [5, 0, 0])


def test_plane_normal_is_normalised():
    scene = scene_from_dict({"static": [{"shape": "plane", "normal": [0, 0, 2], "offset": -1}]})
    assert np.allclose(scene.planes[0].normal, [0, 0, 1]) and scene.planes[0].offset == -1.0


def test_scene_classmethods():
    assert isinstance(Scene.load(SCENES / "box_on_plane.toml"), Scene)
    scene = Scene.from_dict({"static": [_plane_floor()]}, source="mine")
    assert scene.source == "mine" and len(scene.planes) == 1


# ---------------------------------------------------------------------------- centre-of-mass convention
def test_hull_body_position_is_centre_of_mass():
    cube = [[x, y, z] for x in (1, 2) for y in (1, 2) for z in (1, 2)]
    q = np.array([np.cos(0.3), 0, 0, np.sin(0.3)])
    scene = scene_from_dict({"body": [{"shape": "hull", "vertices": cube, "position": [10, 0, 0], "orientation": q.tolist()}]})
    (body,) = scene.bodies
    com_shape = np.array([1.5, 1.5, 1.5])
    assert np.allclose(body.position, [10, 0, 0] + quat_to_matrix(q) @ com_shape)
    (shape,) = body.shapes
    assert np.allclose(shape.local_position, -com_shape)
    # world position of every vertex is unchanged by the shift
    world_loader = body.position + (shape.vertices + shape.local_position) @ quat_to_matrix(body.orientation).T
    world_file = np.array([10, 0, 0]) + np.asarray(cube, float) @ quat_to_matrix(q).T
    assert np.allclose(np.sort(world_loader, axis=0), np.sort(world_file, axis=0))
    assert body.mass == pytest.approx(1000.0)


def test_compound_position_is_centre_of_mass():
    scene = scene_from_dict(
        {
            "body": [
                {
                    "shape": "compound", "position": [0, 0, 5],
                    "parts": [
                        {"shape": "box", "half_extents": [0.5, 0.5, 0.5]},
                        {"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [1, 0, 0], "density": 3000},
                    ],
                }
            ]
        }
    )
    (body,) = scene.bodies
    assert body.mass == pytest.approx(4000.0)
    assert np.allclose(body.position, [0.75, 0, 5])  # (1000 * 0 + 3000 * 1) / 4000
    assert np.allclose([s.local_position for s in body.shapes], [[-0.75, 0, 0], [0.25, 0, 0]])


# ---------------------------------------------------------------------------- generators
def test_stack_generator_size_gap_and_jitter():
    scene = scene_from_dict(
        {"generate": [{"kind": "stack", "count": 5, "size": [2, 2, 1], "position": [1, 1, 0.5], "gap": 0.1,
                       "jitter": 0.05, "seed": 4, "name": "s"}]}
    )
    pos = np.array([b.position for b in scene.bodies])
    assert len(pos) == 5 and [b.name for b in scene.bodies] == [f"s_{i}" for i in range(5)]
    assert np.allclose(pos[:, 2], 0.5 + 1.1 * np.arange(5))
    assert np.all(np.abs(pos[:, :2] - 1.0) <= 0.05) and np.ptp(pos[:, 0]) > 0
    assert np.allclose(scene.bodies[0].shapes[0].half_extents, [1, 1, 0.5])


def test_pyramid_3d_counts_and_touching():
    scene = scene_from_dict({"generate": [{"kind": "pyramid", "base": 4, "layout": "3d", "size": 0.5,
                                           "position": [0, 0, 0.25]}]})
    pos = np.array([b.position for b in scene.bodies])
    assert len(pos) == 16 + 9 + 4 + 1
    base = pos[:16]
    assert np.allclose(np.unique(base[:, 0]), [-0.75, -0.25, 0.25, 0.75])
    assert np.allclose(np.unique(base[:, 1]), [-0.75, -0.25, 0.25, 0.75])
    assert np.allclose(pos[-1], [0, 0, 0.25 + 3 * 0.5])
    assert generators.pyramid_count(20, "2d") == 210 and generators.pyramid_count(4, "3d") == 30


def test_grid_generator_order_and_mass_override():
    scene = scene_from_dict({"generate": [{"kind": "grid", "counts": [3, 2, 2], "spacing": [2, 3, 4],
                                           "origin": [0, 0, 1], "half_extents": 0.5, "mass": 2.0}]})
    pos = np.array([b.position for b in scene.bodies])
    assert len(pos) == 12
    assert np.allclose(pos[:4], [[0, 0, 1], [2, 0, 1], [4, 0, 1], [0, 3, 1]])
    assert np.allclose(pos[-1], [4, 3, 5])
    assert all(b.mass == 2.0 for b in scene.bodies)
    assert np.allclose(scene.bodies[0].inertia, np.eye(3) * 2.0 / 3.0 * 0.5)


def test_grid_generator_seed_controls_the_draws():
    def make(seed):
        return scene_from_dict({"generate": [{"kind": "grid", "counts": [4, 4, 2], "spacing": 2.0, "origin": [0, 0, 1],
                                              "shapes": ["box", "sphere", "capsule", "hull"],
                                              "half_extent_range": [0.2, 0.4], "orientation": "random", "seed": seed}]})

    a, b, c = make(1), make(1), make(2)
    assert [x.shapes[0].kind for x in a.bodies] == [x.shapes[0].kind for x in b.bodies]
    assert all(np.array_equal(x.orientation, y.orientation) for x, y in zip(a.bodies, b.bodies))
    assert not all(np.array_equal(x.orientation, y.orientation) for x, y in zip(a.bodies, c.bodies))
    for body in a.bodies:
        (shape,) = body.shapes
        if shape.kind == "hull":  # generated hulls are centred on their COM
            assert np.allclose(body.position[:2] % 2.0, 0.0)
            assert len(shape.vertices) <= generators.HULL_POINTS


def test_grid_weights_select_shapes():
    scene = scene_from_dict({"generate": [{"kind": "grid", "counts": [10, 10, 1], "spacing": 1.0, "origin": [0, 0, 1],
                                           "shapes": ["box", "sphere"], "weights": [0, 1], "half_extents": 0.3,
                                           "seed": 0}]})
    assert {b.shapes[0].kind for b in scene.bodies} == {"sphere"}


def test_generated_and_explicit_bodies_order():
    scene = scene_from_dict(
        {
            "static": [{"shape": "box", "half_extents": [1, 1, 1], "position": [0, 0, -1], "name": "floor"}],
            "generate": [{"kind": "stack", "count": 2, "half_extents": [0.5, 0.5, 0.5], "position": [0, 0, 0.5]}],
            "body": [{"shape": "sphere", "radius": 0.1, "position": [5, 5, 5], "name": "ball"}],
        }
    )
    assert [b.name for b in scene.bodies] == ["ball", None, None, "floor"]
    assert [b.static for b in scene.bodies] == [False, False, False, True]


# ---------------------------------------------------------------------------- terrain and mesh files
def test_heightfield_matches_anchor_terrain():
    anchor = _anchor("heightfield_pile")["static"][0]
    verts, tris = terrain.heightfield("sines", size=[16, 16], cells=[64, 64], amplitude=0.3, frequency=[1, 1])
    assert np.allclose(verts, anchor["vertices"], atol=JSON_ROUND)
    assert np.array_equal(tris, anchor["faces"])


@pytest.mark.parametrize("function", ["sines", "noise"])
def test_heightfield_triangles_face_up(function):
    params = {"function": function, "amplitude": 0.5, "size": [4, 6], "cells": [8, 12]}
    if function == "noise":
        params["seed"] = 1
    scene = scene_from_dict({"static": [{"shape": "mesh", "heightfield": params, "position": [1, 2, 3]}]})
    (mesh,) = scene.meshes
    v, t = mesh.vertices, mesh.triangles
    assert v.shape == (9 * 13, 3) and t.shape == (2 * 8 * 12, 3)
    normals = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    assert np.all(normals[:, 2] > 0)
    assert np.allclose(v[:, :2].min(axis=0), [-1, -1]) and np.allclose(v[:, :2].max(axis=0), [3, 5])
    assert np.abs(v[:, 2] - 3).max() <= 0.5 + 1e-12


def test_noise_heightfield_is_seeded():
    a = terrain.heightfield("noise", size=[4, 4], cells=[8, 8], amplitude=1.0, seed=5)[0]
    b = terrain.heightfield("noise", size=[4, 4], cells=[8, 8], amplitude=1.0, seed=5)[0]
    c = terrain.heightfield("noise", size=[4, 4], cells=[8, 8], amplitude=1.0, seed=6)[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert np.isclose(np.abs(a[:, 2]).max(), 1.0)


def test_mesh_paths_resolve_against_the_scene_file(tmp_path):
    (tmp_path / "assets").mkdir()
    trimesh.creation.box(extents=(2, 2, 2)).export(tmp_path / "assets" / "block.stl")
    (tmp_path / "scene.toml").write_text(
        "# test scene\n"
        "[[static]]\nshape = 'mesh'\npath = 'assets/block.stl'\nposition = [0, 0, -1]\nscale = 2.0\nname = 'block'\n"
        "[[body]]\nshape = 'hull'\npath = 'assets/block.stl'\nposition = [0, 0, 3]\n"
    )
    scene = load_scene(tmp_path / "scene.toml")
    (mesh,) = scene.meshes
    assert np.allclose(mesh.vertices.min(axis=0), [-2, -2, -3]) and len(mesh.triangles) == 12
    (body,) = scene.bodies
    assert len(body.shapes[0].vertices) == 8 and body.mass == pytest.approx(8000.0)
    # the same dict with base_dir gives the same scene
    scene2 = scene_from_dict({"body": [{"shape": "hull", "path": "assets/block.stl", "position": [0, 0, 3]}]},
                             base_dir=tmp_path)
    assert scene2.bodies[0].mass == pytest.approx(8000.0)


def test_big_mesh_hull_is_simplified_to_extreme_points(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.0)  # 642 hull vertices
    sphere.export(tmp_path / "ball.ply")
    scene = scene_from_dict({"body": [{"shape": "hull", "path": "ball.ply", "position": [0, 0, 0]}]}, base_dir=tmp_path)
    (shape,) = scene.bodies[0].shapes
    assert len(shape.vertices) == MAX_HULL_VERTICES
    assert np.allclose(np.linalg.norm(shape.vertices, axis=1), 1.0)  # every kept point lies on the original sphere
    volume = scene.bodies[0].mass / 1000.0
    assert 0.8 * 4 / 3 * np.pi < volume < 4 / 3 * np.pi


def test_readme_examples_parse_and_load():
    import re
    import tomllib

    text = (SCENES / "README.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", text, re.S)
    assert len(blocks) >= 8
    for block in blocks:
        data = tomllib.loads(block)
        if "[[generate]]   #" in block:  # the skeleton of the top level, entries left empty on purpose
            continue
        scene_from_dict(data, source="README.md", base_dir=SCENES)
