"""Spheres and capsules against boxes, hulls and one-sided mesh triangles.

Hand-computed cases for the face, edge and vertex regions of a box, capsules
lying flat, the triangle rules, and random spheres and capsules near a hull
against the brute-force numpy distance of ``harness.py``. One kernel launch.
"""

import functools
import math

import numpy as np
import pytest

from sandbox.narrowphase.tolerances import FACE_PREFERENCE_ABS

from .harness import assert_points as harness_assert_points
from .harness import capsule, core_polytope_distance, polytope, quat_axis_angle, quat_to_matrix, random_quat, sphere

POS_TOL = 2e-5
"""[m] f32 round-off of positions ~1 m from the origin after a rotation, with margin."""
SEP_TOL = 1e-5
"""[m] Separations are differences of nearby coordinates."""
NORMAL_TOL = 1e-5
"""[1] Unit-vector components after a few f32 rotations."""
EXACT_TOL = 2e-5 + FACE_PREFERENCE_ABS
"""[m] Random cases: f32 round-off on a ~1 m hull, plus the face preference bias of the routine."""
MARGIN = 0.02
"""[m] Speculative margin of the batch (the engine default)."""

ALONG_X = quat_axis_angle([0, 1, 0], math.pi / 2)
ALONG_Y = quat_axis_angle([1, 0, 0], math.pi / 2)
S2 = math.sqrt(0.5)
S3 = math.sqrt(1.0 / 3.0)

CASES = {
    # unit cube at the origin (faces at +-0.5)
    "sphere_on_face": (sphere((0.1, 0.2, 0.74), 0.25), polytope("cube")),
    "face_under_sphere": (polytope("cube"), sphere((0.1, 0.2, 0.74), 0.25)),
    "sphere_on_edge": (sphere((0.6, 0.0, 0.6), 0.2), polytope("cube")),
    "sphere_on_vertex": (sphere((0.6, 0.6, 0.6), 0.2), polytope("cube")),
    "sphere_deep_inside": (sphere((0.0, 0.0, 0.4), 0.2), polytope("cube")),
    "sphere_near_face": (sphere((0.0, 0.0, 0.76), 0.25), polytope("cube")),  # 1 cm gap
    "sphere_far": (sphere((0.0, 0.0, 2.0), 0.25), polytope("cube")),
    # capsule r 0.1, core +-0.3 along x, lying 1 cm deep on the top face, then overhanging the x = 0.5 edge
    "capsule_flat": (capsule((0.1, 0.0, 0.59), ALONG_X, 0.1, 0.3), polytope("cube")),
    "capsule_overhang": (capsule((0.4, 0.0, 0.59), ALONG_X, 0.1, 0.3), polytope("cube")),
    "capsule_upright": (capsule((0.0, 0.0, 0.89), (1, 0, 0, 0), 0.1, 0.3), polytope("cube")),
    # capsule along y, parallel to the top edge x = z = 0.5, above it diagonally
    "capsule_on_edge": (capsule((0.55, 0.0, 0.55), ALONG_Y, 0.1, 0.3), polytope("cube")),
    # triangles: tri_front covers y < x of the square [-2, 2]^2 at z = 0, tri_back y > x
    "sphere_on_triangle": (sphere((0.5, -0.5, 0.24), 0.25), polytope("tri_front")),
    "sphere_not_over_triangle": (sphere((-0.5, 0.5, 0.24), 0.25), polytope("tri_front")),
    "sphere_under_triangle": (sphere((0.5, -0.5, -0.1), 0.25), polytope("tri_front")),
    "capsule_across_seam_front": (capsule((0.0, 0.3, 0.09), ALONG_X, 0.1, 0.5), polytope("tri_front")),
    "capsule_across_seam_back": (capsule((0.0, 0.3, 0.09), ALONG_X, 0.1, 0.5), polytope("tri_back")),
}

RANDOM_CASES = 24


def _random_cases():
    """Spheres and capsules at random poses near the rock, apart within the margin or overlapping."""
    rng = np.random.default_rng(77)
    cases = []
    for i in range(RANDOM_CASES):
        rot_b = random_quat(rng)
        radius = rng.uniform(0.05, 0.2)
        half = 0.0 if i % 2 == 0 else rng.uniform(0.1, 0.4)
        rot_a = random_quat(rng)
        axis = quat_to_matrix(rot_a)[:, 2] * half
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        target = rng.uniform(-0.02, 0.015)

        def signed(t):
            c = t * u
            return core_polytope_distance("rock", np.zeros(3), rot_b, c - axis, c + axis) - radius

        lo, hi = 0.0, 3.0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if signed(mid) < target else (lo, mid)
        t = 0.5 * (lo + hi)
        a = sphere(t * u, radius) if half == 0.0 else capsule(t * u, rot_a, radius, half)
        cases.append((a, polytope("rock", (0, 0, 0), rot_b), signed(t)))
    return cases


@pytest.fixture(scope="module")
def results(harness):
    names = list(CASES)
    rnd = _random_cases()
    out = harness.run([CASES[n] for n in names] + [(a, b) for a, b, _ in rnd], margin=MARGIN)
    return dict(zip(names, out)), list(zip(out[len(names):], [ref for _, _, ref in rnd]))


assert_points = functools.partial(harness_assert_points, pos_tol=POS_TOL, sep_tol=SEP_TOL)


def test_sphere_on_box_face(results):
    m = results[0]["sphere_on_face"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)  # from the sphere to the box
    assert_points(m, [[0.1, 0.2, 0.495]], [-0.01])
    s = results[0]["face_under_sphere"]
    np.testing.assert_allclose(s.normal, [0, 0, 1], atol=NORMAL_TOL)
    np.testing.assert_allclose(s.points, m.points, atol=POS_TOL)


def test_sphere_on_box_edge_region(results):
    m = results[0]["sphere_on_edge"]
    u = np.array([S2, 0.0, S2])  # from the edge (0.5, y, 0.5) to the centre
    sep = 0.1 * math.sqrt(2) - 0.2
    np.testing.assert_allclose(m.normal, -u, atol=NORMAL_TOL)
    assert_points(m, [np.array([0.6, 0.0, 0.6]) - u * (0.2 + sep / 2)], [sep])


def test_sphere_on_box_vertex_region(results):
    m = results[0]["sphere_on_vertex"]
    u = np.array([S3, S3, S3])
    sep = 0.1 * math.sqrt(3) - 0.2
    np.testing.assert_allclose(m.normal, -u, atol=NORMAL_TOL)
    assert_points(m, [np.array([0.6, 0.6, 0.6]) - u * (0.2 + sep / 2)], [sep])


def test_sphere_centre_inside_box_uses_nearest_face(results):
    m = results[0]["sphere_deep_inside"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(m, [[0.0, 0.0, 0.35]], [-0.3])  # centre 0.1 below the top, radius 0.2 more


def test_sphere_margin_and_far(results):
    assert_points(results[0]["sphere_near_face"], [[0.0, 0.0, 0.505]], [0.01])
    assert results[0]["sphere_far"].count == 0


def test_capsule_flat_on_box_gives_two_points(results):
    m = results[0]["capsule_flat"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(m, [[-0.2, 0.0, 0.495], [0.4, 0.0, 0.495]], [-0.01, -0.01])


def test_capsule_overhanging_edge_is_clipped_to_the_face(results):
    m = results[0]["capsule_overhang"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(m, [[0.1, 0.0, 0.495], [0.5, 0.0, 0.495]], [-0.01, -0.01])


def test_capsule_upright_gives_one_point(results):
    m = results[0]["capsule_upright"]
    assert_points(m, [[0.0, 0.0, 0.495]], [-0.01])


def test_capsule_parallel_to_box_edge(results):
    m = results[0]["capsule_on_edge"]
    u = np.array([S2, 0.0, S2])
    sep = 0.05 * math.sqrt(2) - 0.1
    np.testing.assert_allclose(m.normal, -u, atol=NORMAL_TOL)
    assert m.count == 1
    assert abs(m.separation[0] - sep) < SEP_TOL


def test_sphere_on_triangle_front(results):
    m = results[0]["sphere_on_triangle"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(m, [[0.5, -0.5, -0.005]], [-0.01])


def test_triangle_pushes_only_over_itself_and_from_the_front(results):
    assert results[0]["sphere_not_over_triangle"].count == 0
    assert results[0]["sphere_under_triangle"].count == 0


def test_capsule_across_seam_is_split_between_the_triangles(results):
    front, back = results[0]["capsule_across_seam_front"], results[0]["capsule_across_seam_back"]
    for m in (front, back):
        np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    # core x in [-0.5, 0.5] at y = 0.3; the seam y = x crosses it at x = 0.3
    assert_points(front, [[0.3, 0.3, -0.005], [0.5, 0.3, -0.005]], [-0.01, -0.01])
    assert_points(back, [[-0.5, 0.3, -0.005], [0.3, 0.3, -0.005]], [-0.01, -0.01])


def test_random_cores_near_hull_match_brute_force_distance(results):
    for m, ref in results[1]:
        assert m.count >= 1
        assert abs(m.separation.min() - ref) < EXACT_TOL, (m.separation, ref)
