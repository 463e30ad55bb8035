"""Mass properties against closed forms and against each other (hull vs box, compound vs box)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sandbox.scene import scene_from_dict
from sandbox.scene.massprops import (
    MassProperties,
    body_mass_properties,
    box_mass_properties,
    box_mass_properties_batch,
    capsule_mass_properties,
    combine,
    hull_mass_properties,
    sphere_mass_properties,
    transformed,
)
from sandbox.scene.spec import ShapeSpec

EXACT = 1e-9
"""[relative] Closed forms evaluated two ways agree to rounding."""
TESSELLATION = 2e-3
"""[relative] A 128 x 128 capsule mesh under-estimates volume and inertia by ~1e-3."""

RHO = 1000.0


def _quat_axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def test_box_closed_form():
    mp = box_mass_properties([0.5, 1.0, 1.5], RHO)
    m = RHO * 1 * 2 * 3
    assert mp.mass == pytest.approx(m, rel=EXACT)
    assert np.allclose(mp.com, 0)
    # I = m/12 (b^2 + c^2) with full edge lengths a, b, c = 1, 2, 3
    assert np.allclose(mp.inertia, np.diag([m / 12 * 13, m / 12 * 10, m / 12 * 5]), rtol=EXACT)


def test_box_batch_matches_single():
    h = np.array([[0.5, 1.0, 1.5], [0.25, 0.3, 0.4]])
    masses, inertia = box_mass_properties_batch(h, RHO)
    for i in range(2):
        single = box_mass_properties(h[i], RHO)
        assert masses[i] == pytest.approx(single.mass, rel=EXACT)
        assert np.allclose(inertia[i], single.inertia, rtol=EXACT)


def test_sphere_closed_form():
    mp = sphere_mass_properties(0.5, RHO)
    m = RHO * 4 / 3 * np.pi * 0.125
    assert mp.mass == pytest.approx(m, rel=EXACT)
    assert np.allclose(mp.inertia, np.eye(3) * 0.4 * m * 0.25, rtol=EXACT)


def test_capsule_matches_fine_mesh():
    r, h = 0.3, 0.7
    mp = capsule_mass_properties(r, h, RHO)
    mesh = trimesh.creation.capsule(height=2 * h, radius=r, count=[128, 128])
    mesh.density = RHO
    assert mp.mass == pytest.approx(mesh.mass, rel=TESSELLATION)
    assert np.allclose(np.diag(mp.inertia), np.diag(mesh.moment_inertia), rtol=TESSELLATION)
    assert np.allclose(mp.inertia - np.diag(np.diag(mp.inertia)), 0)


def test_capsule_limits():
    # half_height -> 0: a sphere
    tiny = capsule_mass_properties(0.5, 1e-12, RHO)
    sphere = sphere_mass_properties(0.5, RHO)
    assert tiny.mass == pytest.approx(sphere.mass, rel=1e-9)
    assert np.allclose(tiny.inertia, sphere.inertia, rtol=1e-9)
    # very slender: a rod, I_xx -> m L^2 / 12 (the caps lengthen it by r / h = 1e-3, so I by ~2e-3)
    rod = capsule_mass_properties(1e-3, 1.0, RHO)
    assert rod.inertia[0, 0] == pytest.approx(rod.mass * 4.0 / 12.0, rel=5e-3)
    assert rod.inertia[2, 2] == pytest.approx(rod.mass * 1e-6 / 2, rel=5e-3)


def test_capsule_closed_form_by_hand():
    # r = 1, h = 1, rho = 1: m_c = 2 pi, m_s = 4/3 pi
    mp = capsule_mass_properties(1.0, 1.0, 1.0)
    m_c, m_s = 2 * np.pi, 4 / 3 * np.pi
    assert mp.mass == pytest.approx(m_c + m_s)
    assert mp.inertia[2, 2] == pytest.approx(m_c / 2 + m_s * 0.4)
    assert mp.inertia[0, 0] == pytest.approx(m_c * (1 / 4 + 1 / 3) + m_s * (0.4 + 1 + 0.75))


def test_hull_cube_equals_box():
    corners = [[x, y, z] for x in (-0.5, 0.5) for y in (-1, 1) for z in (-1.5, 1.5)]
    hull = hull_mass_properties(corners, RHO)
    box = box_mass_properties([0.5, 1.0, 1.5], RHO)
    assert hull.mass == pytest.approx(box.mass, rel=EXACT)
    assert np.allclose(hull.com, 0, atol=1e-12)
    assert np.allclose(hull.inertia, box.inertia, rtol=EXACT, atol=1e-9)


def test_hull_body_equals_box_body_through_loader():
    corners = [[x, y, z] for x in (0, 1) for y in (0, 2) for z in (0, 3)]
    scene = scene_from_dict(
        {
            "body": [
                {"shape": "hull", "vertices": corners, "position": [0, 0, 0], "mass": 5.0},
                {"shape": "box", "half_extents": [0.5, 1, 1.5], "position": [0.5, 1, 1.5], "mass": 5.0},
            ]
        }
    )
    hull, box = scene.bodies
    assert np.allclose(hull.position, box.position)
    assert hull.mass == box.mass == 5.0
    assert np.allclose(hull.inertia, box.inertia, rtol=EXACT, atol=1e-12)


def test_compound_of_two_boxes_equals_long_box():
    half = ShapeSpec("box", half_extents=np.array([0.5, 0.5, 0.5]))
    parts = [
        ShapeSpec("box", half_extents=half.half_extents, local_position=np.array([-0.5, 0, 0])),
        ShapeSpec("box", half_extents=half.half_extents, local_position=np.array([0.5, 0, 0])),
    ]
    compound = body_mass_properties(parts, RHO)
    long_box = box_mass_properties([1.0, 0.5, 0.5], RHO)
    assert compound.mass == pytest.approx(long_box.mass, rel=EXACT)
    assert np.allclose(compound.com, 0)
    assert np.allclose(compound.inertia, long_box.inertia, rtol=EXACT)


def test_compound_body_through_loader_equals_long_box_body():
    scene = scene_from_dict(
        {
            "body": [
                {
                    "shape": "compound", "position": [0, 0, 1], "orientation": _quat_axis_angle([0, 0, 1], 0.4).tolist(),
                    "parts": [
                        {"shape": "box", "half_extents": [0.5, 0.5, 0.5]},
                        # same cube, rotated 90 degrees about z: a rotated part's inertia must rotate too
                        {"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [1, 0, 0],
                         "orientation": _quat_axis_angle([0, 0, 1], np.pi / 2).tolist()},
                    ],
                },
                {"shape": "box", "half_extents": [1, 0.5, 0.5], "position": [0, 0, 0]},
            ]
        }
    )
    compound, box = scene.bodies
    assert compound.mass == pytest.approx(box.mass, rel=EXACT)
    assert np.allclose(compound.inertia, box.inertia, rtol=EXACT)
    rot = np.array([[np.cos(0.4), -np.sin(0.4), 0], [np.sin(0.4), np.cos(0.4), 0], [0, 0, 1]])
    assert np.allclose(compound.position, [0, 0, 1] + rot @ [0.5, 0, 0])


def test_rotated_part_inertia_is_rotated():
    shape = ShapeSpec("box", half_extents=np.array([1.0, 0.2, 0.3]),
                      local_orientation=_quat_axis_angle([0, 0, 1], np.pi / 2))
    mp = body_mass_properties([shape], RHO)
    swapped = box_mass_properties([0.2, 1.0, 0.3], RHO)
    assert np.allclose(mp.inertia, swapped.inertia, rtol=EXACT, atol=1e-9)


def test_parallel_axis_for_offset_parts():
    s = sphere_mass_properties(1.0, RHO)
    a = transformed(s, [2, 0, 0], [1, 0, 0, 0])
    b = transformed(s, [-2, 0, 0], [1, 0, 0, 0])
    total = combine([a, b])
    assert np.allclose(total.com, 0)
    expected = 2 * s.inertia + 2 * s.mass * np.diag([0, 4, 4])
    assert np.allclose(total.inertia, expected, rtol=EXACT)


def test_mass_overrides_density_and_scales_inertia():
    scene = scene_from_dict(
        {"body": [{"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [0, 0, 0], "mass": 10.0},
                  {"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [0, 0, 0], "density": 10.0}]}
    )
    by_mass, by_density = scene.bodies
    assert by_mass.mass == by_density.mass == pytest.approx(10.0)
    assert np.allclose(by_mass.inertia, np.eye(3) * 10.0 / 6.0)
    assert np.allclose(by_mass.inertia, by_density.inertia)


def test_scaled_keeps_com():
    mp = MassProperties(2.0, np.array([1.0, 2, 3]), np.eye(3))
    s = mp.scaled(3.0)
    assert s.mass == 6.0 and np.allclose(s.com, [1, 2, 3]) and np.allclose(s.inertia, 3 * np.eye(3))
