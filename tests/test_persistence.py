"""Warm-start matching (sandbox/persistence.py) on hand-made contact buffers, no World.

Last step's points are stored (``store_contacts``), this step's points are matched to them
(``match_contacts``): same shape and partner with the same feature id first, else the
nearest old anchor within ``match_distance`` (in body a's frame), else nothing. Tangent
impulses travel as world vectors and come back on this step's basis.
"""

import numpy as np
import pytest

from sandbox.contacts import Contacts
from sandbox.awake import EVERY
from sandbox.dispatch import PARALLEL
from sandbox.persistence import ContactHistory, clear_history, match_contacts, store_contacts
from sandbox.shapes import ShapeTable
from sandbox.solvers.rows import Rows

SUBSTEPS = 4  # impulses are per substep in the rows, per step in the history
MATCH_DISTANCE = 0.05  # [m]
IMPULSE_TOLERANCE = 1e-6
"""[N s] on impulses of order 1: float32 products and sums of three terms (~1e-7 relative),
the per-step scaling by 4 and back by 1/4 being exact."""

# last step's points, grouped by shape as the contact buffer keeps them:
# (shape, partner, feature, anchor in body a's frame [m], per-substep impulse (n, t1, t2) [N s])
OLD = [
    (0, 5, 10, (0.00, 0.0, 0.0), (1.0, 0.3, 0.0)),
    (0, 5, 11, (1.00, 0.0, 0.0), (2.0, 0.0, 0.4)),
    (0, 7, 12, (0.50, 0.0, 0.0), (3.0, 0.1, 0.1)),
    (0, 5, 13, (0.05, 0.0, 0.0), (5.0, -0.2, 0.1)),
    (1, 5, 10, (0.00, 0.0, 0.0), (4.0, 0.0, 0.0)),
]
OLD_BASIS = (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))  # normal +z

# this step's points: (shape, partner, feature, anchor, index into OLD it must inherit or None)
NEW = [
    (0, 5, 11, (0.00, 0.0, 0.0), 1),  # same feature id wins over a nearer anchor
    (0, 5, 99, (0.02, 0.0, 0.0), 0),  # no id: the nearest anchor (0.02 m against 0.03 m)
    (0, 5, 99, (0.035, 0.0, 0.0), 3),  # no id: the nearest anchor, the other one this time
    (0, 5, 99, (0.50, 0.0, 0.0), None),  # 0.45 m from every point of its partner; the 7's is not its partner
    (0, 7, 12, (0.50, 0.01, 0.0), 2),  # the other partner's point
    (1, 5, 10, (0.00, 0.0, 0.0), 4),  # shape 1's own point, not shape 0's of the same id
    (1, 5, 10, (0.06, 0.0, 0.0), 4),  # an id is matched whatever the distance
    (1, 6, 99, (0.00, 0.0, 0.0), None),  # a partner shape 1 did not touch last step
]
ANGLE = 0.7  # [rad] this step's tangent basis turned about the normal


def _rotated_basis(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c, s, 0.0]), np.array([-s, c, 0.0])


class _Buffers:
    def __init__(self):
        self.c = Contacts(16, 4)
        self.rows = Rows(self.c.capacity)
        self.hist = ContactHistory(self.c.capacity, 4)
        self.shapes = ShapeTable(4, 1)
        self.shapes.dynamic_ids.from_numpy(np.array([0, 1, 2, 3], np.int32))
        self.shapes.dynamic_count[None] = 2  # shapes 0 and 1 are dynamic

    def write_points(self, points, basis, impulses=None):
        """Points grouped by shape (shape_first / shape_last as the narrowphase leaves them)."""
        cap = self.c.capacity
        n = len(points)

        def column(values, dtype, width=None):
            full = np.zeros((cap,) if width is None else (cap, width), dtype)
            full[:n] = values
            return full

        shape = np.array([p[0] for p in points])
        self.c.shape_a.from_numpy(column(shape, np.int32))
        self.c.partner.from_numpy(column([p[1] for p in points], np.int32))
        self.c.feature.from_numpy(column([p[2] for p in points], np.int32))
        self.rows.ra_body.from_numpy(column([p[3] for p in points], np.float32, 3))
        self.rows.t1.from_numpy(column(np.tile(basis[0], (n, 1)), np.float32, 3))
        self.rows.t2.from_numpy(column(np.tile(basis[1], (n, 1)), np.float32, 3))
        self.rows.lam.from_numpy(column(impulses if impulses is not None else np.zeros((n, 3)), np.float32, 3))
        first = np.array([np.searchsorted(shape, s) for s in range(4)], np.int32)
        last = np.array([np.searchsorted(shape, s, side="right") for s in range(4)], np.int32)
        self.c.shape_first.from_numpy(first)
        self.c.shape_last.from_numpy(last)
        self.c.count[None] = n


@pytest.fixture(scope="module")
def matched():
    """Last step stored, this step matched: this step's per-substep impulses (n, t1, t2)."""
    buf = _Buffers()
    clear_history(buf.hist)
    buf.write_points(OLD, OLD_BASIS, impulses=[p[4] for p in OLD])
    store_contacts(buf.hist, buf.c, buf.rows, buf.shapes, SUBSTEPS, EVERY, PARALLEL)
    buf.write_points(NEW, _rotated_basis(ANGLE))
    match_contacts(buf.hist, buf.c, buf.rows, MATCH_DISTANCE, 1.0 / SUBSTEPS)
    return buf, buf.rows.lam.to_numpy()[: len(NEW)]


def _expected(old_index, basis):
    """The old point's impulse, its tangent part as a world vector put on ``basis``."""
    if old_index is None:
        return np.zeros(3)
    lam = np.array(OLD[old_index][4])
    tangent = lam[1] * OLD_BASIS[0] + lam[2] * OLD_BASIS[1]  # world [N s]
    return np.array([lam[0], tangent @ basis[0], tangent @ basis[1]])


@pytest.mark.parametrize("q", range(len(NEW)))
def test_each_new_point_inherits_the_impulse_of_its_match(matched, q):
    _, lam = matched
    expected = _expected(NEW[q][4], _rotated_basis(ANGLE))
    np.testing.assert_allclose(lam[q], expected, rtol=0, atol=IMPULSE_TOLERANCE)


def test_tangent_impulse_keeps_its_world_vector_on_a_turned_basis(matched):
    """The re-projected tangent impulse is the same vector in the world: a turning basis does
    not kick a resting contact sideways."""
    _, lam = matched
    t1, t2 = _rotated_basis(ANGLE)
    old = OLD[1][4]
    world_before = old[1] * OLD_BASIS[0] + old[2] * OLD_BASIS[1]
    world_after = lam[0, 1] * t1 + lam[0, 2] * t2
    np.testing.assert_allclose(world_after, world_before, rtol=0, atol=IMPULSE_TOLERANCE)
    assert abs(lam[0, 1]) > 0.1  # the basis did turn: the impulse changed components


def test_history_holds_per_step_impulses_and_the_dynamic_shapes_ranges(matched):
    buf, _ = matched
    n = len(OLD)
    assert buf.hist.count[None] == n
    np.testing.assert_allclose(buf.hist.lam_n.to_numpy()[:n], [SUBSTEPS * p[4][0] for p in OLD], rtol=1e-7)
    np.testing.assert_array_equal(buf.hist.shape_first.to_numpy(), [0, 4, 0, 0])  # shapes 2, 3: not dynamic
    np.testing.assert_array_equal(buf.hist.shape_last.to_numpy(), [4, 5, 0, 0])


def test_a_cleared_history_matches_nothing():
    buf = _Buffers()
    clear_history(buf.hist)
    buf.write_points(NEW, OLD_BASIS, impulses=np.ones((len(NEW), 3)))
    match_contacts(buf.hist, buf.c, buf.rows, MATCH_DISTANCE, 1.0 / SUBSTEPS)
    assert np.all(buf.rows.lam.to_numpy()[: len(NEW)] == 0.0)
