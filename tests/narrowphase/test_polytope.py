"""Polytope pairs (box, hull, one-sided mesh triangle) and polytopes on planes.

Hand-computed cases, the one-sided triangle rules, a stability check on
feature ids, and random hull pairs against the brute-force numpy reference in
``harness.py``. Every case of the file goes into one kernel launch.
"""

import functools
import math

import numpy as np
import pytest

from sandbox.narrowphase.tolerances import SAT_ABS_TOL, SAT_EDGE_REL_TOL

from .harness import assert_points as harness_assert_points
from .harness import (POLYTOPES, place_touching, plane, polytope, polytope_distance, quat_axis_angle, quat_mul,
                      quat_to_matrix, random_quat)

POS_TOL = 2e-5
"""[m] f32 round-off of positions up to ~2 m from the origin after one rotation (ulp 2.4e-7), with margin."""
SEP_TOL = 1e-5
"""[m] Separations are differences of nearby coordinates; same reasoning."""
NORMAL_TOL = 1e-5
"""[1] Unit-vector components after a few f32 rotations."""
MARGIN = 0.02
"""[m] Speculative margin of the batch (the engine default)."""
HULL_EXACT_TOL = 2e-5
"""[m] Random hull pairs: SAT in f32 on shapes ~1 m across placed ~1 m from the origin."""
HULL_EXACT_FRACTION = 0.9
"""[1] Share of random separated hull pairs whose separation must match the reference exactly: the
others may use a face axis that the SAT bias prefers over a slightly better edge axis."""
DEPTH = 0.005
"""[m] Penetration of the rotated box into the triangle mesh."""

CUBE_HALF = 0.5
TILT = quat_mul(quat_axis_angle([1, 0, 0], math.radians(10)), quat_axis_angle([0, 0, 1], math.radians(30)))


def _place_lowest_vertex(name, rot, target) -> tuple:
    """Position that puts the lowest vertex of the rotated polytope at ``target``."""
    v = POLYTOPES[name].vertices @ quat_to_matrix(rot).T
    return tuple(np.asarray(target) - v[np.argmin(v[:, 2])])


# the tilted cube straddling the triangles' shared diagonal y = x: its lowest vertex DEPTH below
# the mesh, 3.5 cm from the seam on tri_back's side, so that its bottom face also dips within the
# margin over tri_front
TILTED_ON_MESH = _place_lowest_vertex("cube", TILT, (0.05, 0.1, -DEPTH))
EDGE_A = quat_axis_angle([0, 1, 0], math.pi / 4)  # top edge along y at z = sqrt(2)/2
EDGE_B = quat_axis_angle([1, 0, 0], math.pi / 4)  # bottom edge along x at z = -sqrt(2)/2
EDGE_DEPTH = 0.01

CASES = {
    # cube (1 m) resting 1 mm deep on a slab whose top is z = 0.5
    "box_on_box": (polytope("slab"), polytope("cube", (0.1, 0.2, 0.999))),
    "box_on_box_reversed": (polytope("cube", (0.1, 0.2, 0.999)), polytope("slab")),
    "box_over_box_margin": (polytope("slab"), polytope("cube", (0.1, 0.2, 1.01))),
    "box_far_from_box": (polytope("slab"), polytope("cube", (0.1, 0.2, 3.0))),
    "edge_edge": (polytope("cube", (0, 0, 0), EDGE_A), polytope("cube", (0, 0, math.sqrt(2) - EDGE_DEPTH), EDGE_B)),
    "box_on_plane": (plane(), polytope("cube", (0.3, -0.1, 0.499))),
    "plane_under_box_swapped": (polytope("cube", (0.3, -0.1, 0.499)), plane()),
    "cylinder_on_plane": (plane(), polytope("cylinder64", (0.0, 0.0, 0.299))),
    "rock_on_plane": (plane(), polytope("rock", (0.0, 0.0, 0.3), random_quat(np.random.default_rng(3)))),
    "tilted_box_on_tri_front": (polytope("cube", TILTED_ON_MESH, TILT), polytope("tri_front")),
    "tilted_box_on_tri_back": (polytope("cube", TILTED_ON_MESH, TILT), polytope("tri_back")),
    "tri_front_under_tilted_box": (polytope("tri_front"), polytope("cube", TILTED_ON_MESH, TILT)),
    # flat cube resting 1 mm deep across the diagonal seam
    "flat_box_on_tri_front": (polytope("cube", (0.3, 0.2, 0.499)), polytope("tri_front")),
    "flat_box_on_tri_back": (polytope("cube", (0.3, 0.2, 0.499)), polytope("tri_back")),
    # cube balanced on an edge (45 degrees about x) 1 mm deep
    "edge_box_on_tri": (polytope("cube", (0.3, -0.5, math.sqrt(0.5) - 0.001), EDGE_B), polytope("tri_front")),
    # beside the triangle (x > 2) with a 1 cm sideways gap, its bottom 5 cm below the mesh plane
    "box_beside_tri": (polytope("cube", (2.51, 0.0, 0.45)), polytope("tri_front")),
    # under the mesh (came through it): the front face must not pull it back up
    "box_under_tri": (polytope("cube", (0.0, 0.5, -0.3)), polytope("tri_front")),
    "cylinder_on_cylinder": (polytope("cylinder64"), polytope("cylinder64", (0.1, 0.0, 0.599))),
    "cube_on_cube": (polytope("cube"), polytope("cube", (0.0, 0.0, 0.999))),
    "cube_half_off_cube": (polytope("cube"), polytope("cube", (0.5, 0.0, 0.999))),
}

STABILITY_RUNS = 8
STABILITY_BASES = {
    "cube_on_slab": "box_on_box",  # the incident face well inside the reference face
    "cube_on_equal_cube": "cube_on_cube",  # coinciding borders: vertices exactly on the side planes
    "cube_half_off_cube": "cube_half_off_cube",  # a pyramid course: two borders coincide, two cross
}
STABILITY_SHIFT = 1e-5
"""[m] Position perturbation of the stability test."""
STABILITY_TURN = 1e-4
"""[rad] Rotation perturbation of the stability test."""

HULL_NAMES = ["tet", "tet2", "rock", "pebble", "cube", "cylinder64"]
HULL_PAIRS = 24


def _hull_cases():
    """Random hull pairs: (a, b, reference signed distance) apart within the margin, or overlapping."""
    rng = np.random.default_rng(2024)
    cases = []
    for i in range(HULL_PAIRS):
        na, nb = rng.choice(HULL_NAMES), rng.choice(HULL_NAMES)
        qa, qb = random_quat(rng), random_quat(rng)
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        touch = place_touching(na, qa, nb, qb, u)
        # even cases apart by up to 1.5 cm (moving by s adds at most s of distance), odd ones overlapping
        shift = rng.uniform(0.002, 0.015) * (1 if i % 2 == 0 else -1)
        pb = touch + shift * u
        sat, dist = polytope_distance(na, np.zeros(3), qa, nb, pb, qb)
        cases.append((polytope(na, (0, 0, 0), qa), polytope(nb, pb, qb), dist if sat > 0 else sat))
    return cases


@pytest.fixture(scope="module")
def results(harness):
    """All cases of this file, one kernel launch."""
    names = list(CASES)
    pairs = [CASES[n] for n in names]
    rng = np.random.default_rng(5)
    for base in STABILITY_BASES.values():
        a, b = CASES[base]
        for _ in range(STABILITY_RUNS):
            turn = quat_axis_angle(rng.normal(size=3), STABILITY_TURN)
            pos = np.asarray(b.pos) + rng.uniform(-STABILITY_SHIFT, STABILITY_SHIFT, 3)
            pairs.append((a, polytope(b.poly, pos, quat_mul(turn, b.rot))))
    hulls = _hull_cases()
    pairs += [(a, b) for a, b, _ in hulls]
    out = harness.run(pairs, margin=MARGIN)
    n = len(names)
    k = STABILITY_RUNS * len(STABILITY_BASES)
    runs = out[n:n + k]
    return {
        "cases": dict(zip(names, out[:n])),
        "stability": {name: runs[i * STABILITY_RUNS:(i + 1) * STABILITY_RUNS] for i, name in enumerate(STABILITY_BASES)},
        "hulls": list(zip(out[n + k:], [ref for _, _, ref in hulls])),
    }


assert_points = functools.partial(harness_assert_points, pos_tol=POS_TOL, sep_tol=SEP_TOL)


def _cube_corners(centre, z):
    cx, cy = centre
    return [[cx + sx * CUBE_HALF, cy + sy * CUBE_HALF, z] for sx in (-1, 1) for sy in (-1, 1)]


def test_box_resting_on_box_gives_four_corners(results):
    m = results["cases"]["box_on_box"]
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    assert_points(m, _cube_corners((0.1, 0.2), 0.4995), [-0.001] * 4)
    assert len(set(m.feature.tolist())) == 4


def test_box_on_box_reversed_pair_gives_same_points_and_opposite_normal(results):
    d, r = results["cases"]["box_on_box"], results["cases"]["box_on_box_reversed"]
    np.testing.assert_allclose(r.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(r, _cube_corners((0.1, 0.2), 0.4995), [-0.001] * 4)


def test_box_over_box_within_margin_gives_positive_separation(results):
    m = results["cases"]["box_over_box_margin"]
    assert_points(m, _cube_corners((0.1, 0.2), 0.505), [0.01] * 4)


def test_far_apart_gives_no_points(results):
    assert results["cases"]["box_far_from_box"].count == 0


def test_crossed_edges_give_one_point_along_cross_product(results):
    m = results["cases"]["edge_edge"]
    # top edge of a along y, bottom edge of b along x: the normal is along y x x = -z, oriented a -> b: +z
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    assert_points(m, [[0.0, 0.0, math.sqrt(0.5) - EDGE_DEPTH / 2]], [-EDGE_DEPTH])
    assert m.feature[0] >> 28 == 2  # edge-edge id


def test_box_on_plane_gives_bottom_vertices(results):
    m = results["cases"]["box_on_plane"]
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    assert_points(m, _cube_corners((0.3, -0.1), -0.0005), [-0.001] * 4)
    assert sorted(m.feature.tolist()) == [0, 2, 4, 6]  # vertex index 4x + 2y + z with z < 0


def test_swapped_kinds_flip_the_normal(results):
    d, s = results["cases"]["box_on_plane"], results["cases"]["plane_under_box_swapped"]
    np.testing.assert_allclose(s.normal, -d.normal, atol=NORMAL_TOL)
    np.testing.assert_allclose(s.points, d.points, atol=POS_TOL)
    assert s.feature.tolist() == d.feature.tolist()
    d, s = results["cases"]["tilted_box_on_tri_front"], results["cases"]["tri_front_under_tilted_box"]
    np.testing.assert_allclose(s.normal, -d.normal, atol=NORMAL_TOL)
    assert s.feature.tolist() == d.feature.tolist()


def test_hull_on_plane_reduces_to_a_wide_quad(results):
    m = results["cases"]["cylinder_on_plane"]  # 32 bottom vertices, 1 mm deep
    assert m.count == 4
    np.testing.assert_allclose(m.separation, -0.001, atol=SEP_TOL)
    p = m.points[:, :2]
    hull_order = np.argsort(np.arctan2(p[:, 1], p[:, 0]))
    x, y = p[hull_order, 0], p[hull_order, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert area > 0.49  # [m^2] the largest quad in the 32-gon of radius 0.5 is the square, 0.5


def test_rotated_hull_on_plane_finds_deepest_vertex(results):
    m = results["cases"]["rock_on_plane"]
    rock = CASES["rock_on_plane"][1]
    z = (POLYTOPES["rock"].vertices @ quat_to_matrix(rock.rot).T)[:, 2] + rock.pos[2]
    assert m.count == min(4, int(np.sum(z < MARGIN)))
    assert abs(m.separation.min() - z.min()) < SEP_TOL


@pytest.mark.parametrize("name", ["tilted_box_on_tri_front", "tilted_box_on_tri_back"])
def test_box_on_mesh_gets_triangle_normal_and_never_a_downward_push(results, name):
    m = results["cases"][name]
    assert m.count >= 1
    # from the box to the triangle: -z, so the box is pushed up, never down or sideways
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert m.separation.min() > -DEPTH - SEP_TOL


def test_box_on_mesh_finds_the_deepest_vertex_on_its_triangle(results):
    assert abs(results["cases"]["tilted_box_on_tri_back"].separation.min() + DEPTH) < SEP_TOL
    assert results["cases"]["tilted_box_on_tri_front"].separation.min() > -DEPTH + SEP_TOL


def test_flat_box_across_seam_gets_face_normal_from_both_triangles(results):
    for name in ("flat_box_on_tri_front", "flat_box_on_tri_back"):
        m = results["cases"][name]
        assert m.count >= 3
        np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
        np.testing.assert_allclose(m.separation, -0.001, atol=SEP_TOL)


def test_box_on_edge_on_mesh_gives_the_edge_ends(results):
    m = results["cases"]["edge_box_on_tri"]
    np.testing.assert_allclose(m.normal, [0, 0, -1], atol=NORMAL_TOL)
    assert_points(m, [[-0.2, -0.5, -0.0005], [0.8, -0.5, -0.0005]], [-0.001, -0.001])


def test_box_beside_or_under_mesh_triangle_is_not_lifted(results):
    assert results["cases"]["box_beside_tri"].count == 0
    assert results["cases"]["box_under_tri"].count == 0


def test_64_vertex_hulls_stack(results):
    m = results["cases"]["cylinder_on_cylinder"]
    assert m.count == 4
    np.testing.assert_allclose(m.normal, [0, 0, 1], atol=NORMAL_TOL)
    np.testing.assert_allclose(m.separation, -0.001, atol=SEP_TOL)


@pytest.mark.parametrize("config", list(STABILITY_BASES))
def test_resting_box_keeps_its_feature_ids_under_tiny_perturbations(results, config):
    reference = sorted(results["cases"][STABILITY_BASES[config]].feature.tolist())
    assert len(reference) == 4
    for m in results["stability"][config]:
        assert m.count == 4
        assert sorted(m.feature.tolist()) == reference


def test_random_hull_pairs_match_brute_force_distance(results):
    exact = 0
    apart = 0
    for m, ref in results["hulls"]:
        assert m.count >= 1  # within the margin (or overlapping) always gives a contact
        s = m.separation.min()
        bias = SAT_EDGE_REL_TOL * abs(ref) + SAT_ABS_TOL  # what the face-over-edge preference may cost
        assert abs(s - ref) < bias, (s, ref)
        if ref > 0:
            apart += 1
            exact += abs(s - ref) < HULL_EXACT_TOL
        else:
            assert abs(s - ref) < HULL_EXACT_TOL, (s, ref)  # overlap: the deepest point is the SAT depth
    assert exact >= HULL_EXACT_FRACTION * apart
