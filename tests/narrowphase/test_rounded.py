"""Rounded pairs (sphere, capsule) and rounded shapes on planes, against hand-computed contacts.

All cases of this file run in one kernel launch (``manifolds`` fixture); each
test checks its own slice.
"""

import functools
import math

import numpy as np
import pytest

from .harness import assert_points as harness_assert_points
from .harness import capsule, plane, quat_axis_angle, sphere

POS_TOL = 1e-5
"""[m] f32 round-off of positions ~1 m from the origin (ulp 1.2e-7), with margin."""
SEP_TOL = 1e-5
"""[m] Same for separations, which are differences of such positions."""
NORMAL_TOL = 1e-5
"""[1] Unit-vector components after a few f32 rotations."""
MARGIN = 0.02
"""[m] Speculative margin of the batch (the engine default)."""

ALONG_X = quat_axis_angle([0, 1, 0], math.pi / 2)  # capsule core (local z) turned onto the x axis
ALONG_Y = quat_axis_angle([1, 0, 0], math.pi / 2)

CASES = {
    # plane z = 0, sphere r 0.5 sinking 1 cm
    "plane_sphere": (plane(), sphere([0.3, -0.2, 0.49], 0.5)),
    # capsule (r 0.2, core +-0.5 along x) lying flat, 1 cm deep: both ends
    "plane_capsule_flat": (plane(), capsule([0.0, 0.0, 0.19], ALONG_X, 0.2, 0.5)),
    # the same capsule 30 degrees from horizontal: only the low end touches
    "plane_capsule_tilted": (plane(), capsule([0.0, 0.0, 0.44], quat_axis_angle([0, 1, 0], math.pi / 3), 0.2, 0.5)),
    "sphere_sphere": (sphere([0.0, 0.0, 0.0], 0.5), sphere([0.9, 0.0, 0.0], 0.5)),
    # sphere r 0.3 beside a vertical capsule (r 0.2, core z in [-0.5, 0.5]), 5 cm deep
    "sphere_capsule": (sphere([0.45, 0.0, 0.2], 0.3), capsule([0.0, 0.0, 0.0], [1, 0, 0, 0], 0.2, 0.5)),
    # same, sphere above the capsule's end cap
    "sphere_capsule_cap": (sphere([0.0, 0.0, 0.95], 0.3), capsule([0.0, 0.0, 0.0], [1, 0, 0, 0], 0.2, 0.5)),
    # two parallel capsules along x, b shifted +0.3 in x and resting 1 cm deep on a
    "capsule_capsule_parallel": (capsule([0.0, 0.0, 0.0], ALONG_X, 0.2, 0.5), capsule([0.3, 0.0, 0.39], ALONG_X, 0.2, 0.5)),
    # crossed at 90 degrees
    "capsule_capsule_crossed": (capsule([0.0, 0.0, 0.0], ALONG_X, 0.2, 0.5), capsule([0.0, 0.0, 0.39], ALONG_Y, 0.2, 0.5)),
    # swapped argument orders
    "sphere_plane": (sphere([0.3, -0.2, 0.49], 0.5), plane()),
    "capsule_sphere": (capsule([0.0, 0.0, 0.0], [1, 0, 0, 0], 0.2, 0.5), sphere([0.45, 0.0, 0.2], 0.3)),
    # far apart, and apart but within the margin
    "sphere_sphere_far": (sphere([0.0, 0.0, 0.0], 0.5), sphere([3.0, 0.0, 0.0], 0.5)),
    "sphere_sphere_margin": (sphere([0.0, 0.0, 0.0], 0.5), sphere([0.0, 1.01, 0.0], 0.5)),
    "capsule_capsule_margin": (capsule([0.0, 0.0, 0.0], ALONG_X, 0.2, 0.5), capsule([0.0, 0.0, 0.41], ALONG_Y, 0.2, 0.5)),
    "plane_sphere_beyond_margin": (plane(), sphere([0.0, 0.0, 0.53], 0.5)),
}


@pytest.fixture(scope="module")
def manifolds(harness):
    names = list(CASES)
    return dict(zip(names, harness.run([CASES[n] for n in names], margin=MARGIN)))


assert_points = functools.partial(harness_assert_points, pos_tol=POS_TOL, sep_tol=SEP_TOL)


def test_plane_sphere_one_point_midway(manifolds):
    m = manifolds["plane_sphere"]
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    assert_points(m, [[0.3, -0.2, -0.005]], [-0.01])


def test_plane_capsule_flat_gives_both_ends(manifolds):
    m = manifolds["plane_capsule_flat"]
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    assert_points(m, [[-0.5, 0.0, -0.005], [0.5, 0.0, -0.005]], [-0.01, -0.01])
    assert sorted(m.feature.tolist()) == [0, 1]


def test_plane_capsule_tilted_gives_low_end_only(manifolds):
    m = manifolds["plane_capsule_tilted"]
    # core turned 60 degrees from vertical: low end at z = 0.44 - 0.5 cos(60 deg) = 0.19, surface 0.2 lower
    low = 0.44 - 0.5 * math.cos(math.pi / 3)
    assert m.count == 1
    assert abs(m.separation[0] - (low - 0.2)) < SEP_TOL


def test_sphere_sphere_normal_along_centres(manifolds):
    m = manifolds["sphere_sphere"]
    np.testing.assert_allclose(m.normal, [1, 0, 0], atol=NORMAL_TOL)
    assert_points(m, [[0.45, 0.0, 0.0]], [-0.1])


def test_sphere_capsule_side_and_cap(manifolds):
    m = manifolds["sphere_capsule"]
    np.testing.assert_allclose(m.normal, [-1, 0, 0], atol=NORMAL_TOL)  # from the sphere to the capsule
    assert_points(m, [[0.175, 0.0, 0.2]], [-0.05])
    m = manifolds["sphere_capsule_cap"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(m, [[0.0, 0.0, 0.675]], [-0.05])


def test_capsule_capsule_parallel_gives_two_points_on_common_extent(manifolds):
    m = manifolds["capsule_capsule_parallel"]
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    # b's core spans x in [-0.2, 0.8], a's [-0.5, 0.5]: common extent [-0.2, 0.5]
    assert_points(m, [[-0.2, 0.0, 0.195], [0.5, 0.0, 0.195]], [-0.01, -0.01])


def test_capsule_capsule_crossed_gives_one_point(manifolds):
    m = manifolds["capsule_capsule_crossed"]
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    assert_points(m, [[0.0, 0.0, 0.195]], [-0.01])


def test_swapped_order_flips_normal_only(manifolds):
    for direct, swapped in (("plane_sphere", "sphere_plane"), ("sphere_capsule", "capsule_sphere")):
        d, s = manifolds[direct], manifolds[swapped]
        np.testing.assert_allclose(s.normal, -d.normal, atol=NORMAL_TOL)
        np.testing.assert_allclose(s.points, d.points, atol=POS_TOL)
        np.testing.assert_allclose(s.separation, d.separation, atol=SEP_TOL)


def test_far_apart_gives_no_points(manifolds):
    assert manifolds["sphere_sphere_far"].count == 0
    assert manifolds["plane_sphere_beyond_margin"].count == 0  # 3 cm gap > 2 cm margin


def test_within_margin_gives_positive_separation(manifolds):
    m = manifolds["sphere_sphere_margin"]
    np.testing.assert_allclose(m.normal, [0, 1, 0], atol=NORMAL_TOL)
    assert_points(m, [[0.0, 0.505, 0.0]], [0.01])
    m = manifolds["capsule_capsule_margin"]
    assert_points(m, [[0.0, 0.0, 0.205]], [0.01])
