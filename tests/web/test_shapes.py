"""The web sandbox's pure-Python parts: grouping bodies into batched meshes, debris placement
and the static geometry (no browser, no Taichi)."""

from types import SimpleNamespace

import numpy as np
import pytest

from sandbox import SandboxError, Scene
from sandbox.scene import BodySpec, PlaneSpec, ShapeSpec
from web.debris import DEBRIS_MIXES, debris_bodies
from web.render import PANEL_SHIFT, camera_for
from web.shapes import body_shape, shape_mesh, static_meshes


def _body(*shapes, static=False):
    return BodySpec(shapes=list(shapes), position=np.zeros(3), static=static)


def _box(h):
    return ShapeSpec("box", half_extents=np.asarray(h, dtype=np.float64))


def test_boxes_of_any_size_share_one_mesh_scaled_per_instance():
    keys = {body_shape(_body(_box(h)))[0] for h in ([0.5, 0.5, 0.5], [0.1, 0.2, 0.3], [2.0, 1.0, 0.5])}
    assert keys == {("box",)}
    key, scale = body_shape(_body(_box([0.1, 0.2, 0.3])))
    mesh = shape_mesh(key, _body(_box([0.1, 0.2, 0.3])))
    extent = (mesh.vertices * scale).max(axis=0) - (mesh.vertices * scale).min(axis=0)
    assert np.allclose(extent, [0.2, 0.4, 0.6], atol=1e-6)


def test_spheres_share_a_mesh_and_capsules_share_one_per_aspect_ratio():
    assert body_shape(_body(ShapeSpec("sphere", radius=0.2)))[0] == body_shape(_body(ShapeSpec("sphere", radius=3.0)))[0]
    a = body_shape(_body(ShapeSpec("capsule", radius=0.1, half_height=0.2)))
    b = body_shape(_body(ShapeSpec("capsule", radius=0.2, half_height=0.4)))
    c = body_shape(_body(ShapeSpec("capsule", radius=0.2, half_height=0.2)))
    assert a[0] == b[0] != c[0] and np.allclose(b[1], 0.2)
    mesh = shape_mesh(b[0], _body(ShapeSpec("capsule", radius=0.2, half_height=0.4)))
    z = mesh.vertices[:, 2] * 0.2
    assert np.isclose(z.max(), 0.6, atol=1e-6) and np.isclose(z.min(), -0.6, atol=1e-6)  # half_height + radius


def test_hulls_and_compounds_are_unique_meshes_in_the_body_frame():
    rng = np.random.default_rng(0)
    hull_a = ShapeSpec("hull", vertices=rng.uniform(-1, 1, (12, 3)))
    hull_b = ShapeSpec("hull", vertices=rng.uniform(-1, 1, (12, 3)))
    assert body_shape(_body(hull_a))[0] != body_shape(_body(hull_b))[0]
    same_points = ShapeSpec("hull", vertices=hull_a.vertices.copy())  # a key by content, not by object
    assert body_shape(_body(hull_a))[0] == body_shape(_body(same_points))[0]
    offset = ShapeSpec("box", half_extents=np.array([0.5, 0.5, 0.5]), local_position=np.array([2.0, 0.0, 0.0]))
    compound = _body(_box([0.5, 0.5, 0.5]), offset)
    key, scale = body_shape(compound)
    assert key[0] == "mesh" and np.allclose(scale, 1.0)
    mesh = shape_mesh(key, compound)
    assert np.isclose(mesh.vertices[:, 0].max(), 2.5) and np.isclose(mesh.vertices[:, 0].min(), -0.5)


def test_plane_slab_top_is_the_plane():
    scene = Scene(source="<test>", planes=[PlaneSpec(normal=np.array([0.0, 0.0, 1.0]), offset=1.5)])
    ((name, verts, faces, _),) = static_meshes(scene, half_size=10.0)
    assert name == "/static/plane_0" and len(faces) == 12
    assert np.isclose(verts[:, 2].max(), 1.5) and np.isclose(verts[:, 0].max(), 10.0)


def _snapshot(positions, static=None):
    n = len(positions)
    static = static if static is not None else [False] * n
    return SimpleNamespace(positions=np.asarray(positions, dtype=np.float32),
                           bodies=tuple(_body(_box([0.5, 0.5, 0.5]), static=s) for s in static))


@pytest.mark.parametrize("mix", DEBRIS_MIXES)
def test_debris_lands_above_every_dynamic_body_and_is_seeded(mix):
    snap = _snapshot([[0, 0, 0.5], [3, 1, 4.0], [-2, -1, 0.5], [0, 0, 50.0]], static=[False, False, False, True])
    bodies = debris_bodies(snap, 30, mix, seed=3)
    assert len(bodies) == 30
    lowest = min(b.position[2] for b in bodies)
    assert lowest > 4.0 + 0.5  # above the highest dynamic body (the static one at 50 m is ignored)
    kinds = {s.kind for b in bodies for s in b.shapes}
    expected = {"boxes": {"box"}, "spheres": {"sphere"}, "hulls": {"hull"}, "capsules": {"capsule"}}
    assert kinds == expected.get(mix, kinds) and (mix != "mixed" or len(kinds) >= 3)
    again = debris_bodies(snap, 30, mix, seed=3)
    assert all(np.array_equal(a.position, b.position) for a, b in zip(bodies, again))


def test_debris_errors_are_sandbox_errors():
    snap = _snapshot([[0, 0, 0.5]])
    with pytest.raises(SandboxError, match="unknown debris mix 'gravel'"):
        debris_bodies(snap, 5, "gravel", seed=0)


def test_camera_frames_the_bodies_from_the_front_left_of_the_panel():
    """It looks at a point right of the bodies' centre, so they sit in the part of the view the
    panel (docked right) leaves free, and from in front (-y) and above."""
    eye, target = camera_for(np.array([[-10.0, 0.0, 0.0], [10.0, 0.0, 4.0]]))
    radius = 0.6 * np.linalg.norm([20.0, 0.0, 4.0])
    assert np.allclose(target, [PANEL_SHIFT * radius, 0.0, 2.0])
    assert 0.0 < PANEL_SHIFT < 1.0
    assert eye[1] < -10.0 and eye[2] > target[2]
