"""Mass splitting (sandbox/solvers/mass_splitting.py, block_adjacency.py) piece by piece.

The body adjacency on hand-made contact buffers (every dynamic endpoint of every block
listed once, per body, in sorted order; the split counts; scale x weight = 1), then one
Jacobi sweep of point mass splitting on a box resting on a plane against the impulses
worked out by hand: each corner is solved on a share 1 / s of the box (s = 4 corners over
the split relaxation, never below one sub-body), and the merged velocity is every impulse
applied to the whole box.
"""

import numpy as np
import pytest
import taichi as ti

from sandbox import Scene, World
from sandbox.awake import EVERY
from sandbox.bodies import Bodies
from sandbox.contacts import Contacts
from sandbox.solvers import block_adjacency as ba
from sandbox.solvers import mass_splitting as ms
from sandbox.solvers.rows import RELAX, Rows
from tests.helpers import TEST_ARCH, box_body, scene_dict

BODIES = 40
STATIC = [3, 17, 39]  # static bodies own no slots
ISOLATED = 20  # a dynamic body in no block: no slots, and not split (its count is taken as 1)
POINTS = 300
MANIFOLDS = 90


def _blocks(seed: int, count: int):
    """Random blocks: body a is dynamic (it enumerated the pair), b any other body."""
    rng = np.random.default_rng(seed)
    dynamic = np.setdiff1d(np.arange(BODIES), STATIC + [ISOLATED])
    others = np.setdiff1d(np.arange(BODIES), [ISOLATED])
    a = rng.choice(dynamic, count)
    b = np.array([rng.choice(others[others != x]) for x in a])
    return a.astype(np.int32), b.astype(np.int32)


def _fill(field, values, capacity):
    """The field's first entries from ``values``, the rest zero."""
    full = np.zeros(capacity, np.int32)
    full[:len(values)] = values
    field.from_numpy(full)


@pytest.fixture(scope="module")
def buffers():
    bodies = Bodies(64)
    inv_mass = np.ones(BODIES, np.float32)
    inv_mass[STATIC] = 0.0
    eye = np.tile(np.eye(3, dtype=np.float32), (BODIES, 1, 1))
    bodies.upload({"inv_mass": inv_mass, "inertia": eye, "inv_inertia": eye, "pos": np.zeros((BODIES, 3)),
                   "rot": np.tile([1.0, 0.0, 0.0, 0.0], (BODIES, 1)), "lin_vel": np.zeros((BODIES, 3)),
                   "ang_vel": np.zeros((BODIES, 3))})
    c = Contacts(128, 4)
    a, b = _blocks(1, POINTS)
    _fill(c.body_a, a, c.capacity)
    _fill(c.body_b, b, c.capacity)
    c.count[None] = POINTS
    ma, mb = _blocks(2, MANIFOLDS)
    _fill(c.m_body_a, ma, c.pair_capacity)
    _fill(c.m_body_b, mb, c.pair_capacity)
    c.manifold_count[None] = MANIFOLDS
    # every block can act (block_adjacency._point_can_act): its points touch (separation 0)
    c.sep.from_numpy(np.zeros(c.capacity, np.float32))
    c.m_start.from_numpy(np.arange(c.pair_capacity, dtype=np.int32) % POINTS)
    c.m_count.from_numpy(np.ones(c.pair_capacity, np.int32))
    blocks = {ba.PER_POINT: (a, b), ba.PER_MANIFOLD: (ma, mb)}
    return ba.BlockScratch(c.capacity, 64), c, bodies, Rows(c.capacity), blocks


KINDS = [ba.PER_POINT, ba.PER_MANIFOLD]
KIND_IDS = ["per-point", "per-manifold"]


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
def test_adjacency_lists_every_dynamic_endpoint_once_in_sorted_order(buffers, kind):
    scratch, c, bodies, rows, blocks = buffers
    ba.build_adjacency(scratch, c, bodies, rows, kind, ba.MODE_SPLIT, 1.0)
    a, b = blocks[kind]
    start = scratch.adj_start.to_numpy()
    adj = scratch.adj.to_numpy()
    assert scratch.block_count[None] == len(a)
    for i in range(BODIES):
        # endpoint 2k is block k's body a, 2k + 1 its body b
        expected = sorted([2 * k for k in np.flatnonzero(a == i)] + [2 * k + 1 for k in np.flatnonzero(b == i)])
        if i in STATIC:
            expected = []
        if i == ISOLATED:
            assert expected == []
        np.testing.assert_array_equal(adj[start[i]:start[i + 1]], expected, err_msg=f"body {i}")
    assert start[BODIES] == scratch.adj_total[None] == sum(np.isin(x, STATIC, invert=True).sum() for x in (a, b))


@pytest.mark.parametrize("kind", KINDS, ids=KIND_IDS)
@pytest.mark.parametrize("omega", [1.0, 0.7, 1.6])
def test_split_scale_is_the_block_count_over_omega_and_weight_its_inverse(buffers, kind, omega):
    """Mass splitting: scale = max(1, n_b / omega), weight = 1 / scale (n_b = blocks touching
    body b that can act); scale x weight = 1, so an impulse reaches the merged body with its
    full mass."""
    scratch, c, bodies, rows, blocks = buffers
    ba.build_adjacency(scratch, c, bodies, rows, kind, ba.MODE_SPLIT, omega)
    a, b = blocks[kind]
    counts = np.bincount(np.concatenate([a, b]), minlength=BODIES)
    counts = np.maximum(counts, 1)  # a body in no block (ISOLATED at least) is not split
    dynamic = np.setdiff1d(np.arange(BODIES), STATIC)
    assert counts[dynamic].max() >= 5  # split counts from 1 to a crowded body
    scale = scratch.scale.to_numpy()[:BODIES]
    weight = scratch.weight.to_numpy()[:BODIES]
    # float32: one division each (half an ulp), their product within two ulps of 1
    split = np.maximum(counts[dynamic] / omega, 1.0)
    np.testing.assert_allclose(scale[dynamic], split, rtol=2 ** -23)
    np.testing.assert_allclose(weight[dynamic], 1.0 / split, rtol=2 ** -22)
    np.testing.assert_allclose(scale * weight, 1.0, rtol=2 ** -22)


@pytest.mark.parametrize("omega", [1.0, 0.25])
def test_jacobi_scale_is_one_global_factor(buffers, omega):
    """Projected Jacobi: the same schedule with one split factor 1 / omega for every body."""
    scratch, c, bodies, rows, _ = buffers
    ba.build_adjacency(scratch, c, bodies, rows, ba.PER_POINT, ba.MODE_JACOBI, omega)
    np.testing.assert_allclose(scratch.scale.to_numpy()[:BODIES], 1.0 / omega, rtol=2 ** -23)
    np.testing.assert_allclose(scratch.weight.to_numpy()[:BODIES], omega, rtol=2 ** -23)


@pytest.mark.parametrize("omega", [0.02, 0.25])
@pytest.mark.parametrize("impact", [False, True], ids=["resting", "impact"])
def test_bounded_jacobi_takes_its_busiest_bodys_split_as_its_one_factor(buffers, omega, impact):
    """The ``jacobi`` solver's default (MODE_JACOBI_BOUNDED): every body gets one factor, the
    larger of 1 / omega and the busiest dynamic body's split, every block counted: n_b over the
    split relaxation, n_b alone while one of its blocks is an impact (new and fast). Static
    bodies own no blocks. omega 0.02 lets the floor win, 0.25 the busiest body."""
    from sandbox.solvers.contact_spring import RESTITUTION_THRESHOLD, SPLIT_BOUND

    scratch, c, bodies, rows, blocks = buffers
    a, b = blocks[ba.PER_POINT]
    counts = np.bincount(np.concatenate([a, b]), minlength=BODIES).astype(np.float64)
    counts[STATIC] = 0.0
    relax = np.full(BODIES, 1.8)
    approach = np.zeros(rows.capacity, np.float32)
    if impact:  # one point of the busiest body closes at 10 m/s with no warm start
        q = int(np.flatnonzero((a == counts.argmax()) | (b == counts.argmax()))[0])
        approach[q] = -10.0
        relax[[a[q], b[q]]] = 1.0
    rows.params[SPLIT_BOUND] = 1.8
    rows.params[RESTITUTION_THRESHOLD] = 1.0
    rows.approach.from_numpy(approach)
    try:
        ba.build_adjacency(scratch, c, bodies, rows, ba.PER_POINT, ba.MODE_JACOBI_BOUNDED, omega)
    finally:
        rows.approach.from_numpy(np.zeros(rows.capacity, np.float32))
    busiest = (counts / relax).max()
    expected = max(1.0 / omega, busiest)
    assert (1.0 / omega > busiest) == (omega == 0.02)
    np.testing.assert_allclose(scratch.scale.to_numpy()[:BODIES], expected, rtol=2 ** -23)
    np.testing.assert_allclose(scratch.weight.to_numpy()[:BODIES], 1.0 / expected, rtol=2 ** -22)
    np.testing.assert_allclose(scratch.scale_idle.to_numpy()[:BODIES], expected, rtol=2 ** -23)


HALF = np.array([0.3, 0.5, 0.2])  # [m] the box's half extents: no symmetry makes it easy
MASS = 12.0  # [kg]
SINK = 1e-3  # [m] the box starts this deep, so the relax rows have no speculative target
IMPULSE_RTOL = 1e-5
"""Relative, on impulses and velocities: float32 rows (unit responses, scaled and inverted,
dot products of three terms), a few ulp each, against float64 by hand."""


def _corner_response(rx, ry):
    """Unit response of the box at a bottom corner along the normal z: 1/m + (r x n) I^-1 (r x n),
    with r x n = (-ry, rx, 0) for n = -z and the box's principal inertias m (h_j^2 + h_k^2) / 3."""
    hx, hy, hz = HALF
    ixx, iyy = MASS * (hy**2 + hz**2) / 3.0, MASS * (hx**2 + hz**2) / 3.0
    return 1.0 / MASS + ry**2 / ixx + rx**2 / iyy


@pytest.fixture(scope="module")
def resting_box():
    scene = Scene.from_dict(scene_dict([box_body([0.0, 0.0, HALF[2] - SINK], half=HALF, mass=MASS)],
                                       solver="mass-splitting", iterations=1))
    world = World(scene, arch=TEST_ARCH)
    world.step(1)  # finds the 4 corner contacts and prepares their rows at the starting pose
    return world


@pytest.mark.parametrize("v0, w0", [((0.0, 0.0, -1.0), (0.0, 0.0, 0.0)), ((0.2, 0.0, -1.0), (2.5, 0.0, 0.0))],
                         ids=["falling", "falling-and-turning"])
def test_one_sweep_on_a_resting_box_gives_the_impulses_worked_out_by_hand(resting_box, v0, w0):
    """Corner q closes its approach speed u_q = -(v0 + w0 x r_q) . z alone on a share of the box:
    lambda_q = max(u_q, 0) / (s k_q) (k_q the corner's unit response on the whole box, the
    split scales it by s = 4 blocks / the split relaxation). The merge weights each share's
    change by 1/s, which makes it the whole box under all four impulses: v = v0 + sum(lambda) z / m,
    w = w0 + I^-1 sum(r_q x lambda_q z). Friction rows add nothing: their cone is mu x 0."""
    world = resting_box
    buf = world.buf
    c = world.contacts(["point", "normal", "separation"])
    assert len(c["point"]) == 4 and np.all(c["separation"] < 0.0)
    np.testing.assert_allclose(c["normal"], np.tile([0.0, 0.0, -1.0], (4, 1)), atol=1e-6)  # from the box (a) to the plane
    split = max(1.0, 4.0 / world.settings.split_relaxation)  # the box is split in 4, over-relaxed
    np.testing.assert_allclose(buf.blocks.scale.to_numpy()[0], split, rtol=2 ** -23)
    # back to the pose the rows were prepared at, with the chosen velocities and no impulses yet
    buf.bodies.pos[0] = [0.0, 0.0, HALF[2] - SINK]
    buf.bodies.rot[0] = [1.0, 0.0, 0.0, 0.0]
    buf.bodies.moved.fill(0.0)
    buf.bodies.lin_vel[0] = v0
    buf.bodies.ang_vel[0] = w0
    buf.rows.lam.fill(0.0)
    ms.jacobi_sweep(buf.blocks, buf.rows, buf.contacts, buf.bodies, EVERY, ba.PER_POINT, RELAX, True, 0,
                    ti.math.vec3(0.0), 0.0, 0)

    r = buf.rows.ra.to_numpy()[:4].astype(np.float64)
    np.testing.assert_allclose(np.abs(r[:, :2]), np.tile(HALF[:2], (4, 1)), atol=1e-6)  # the bottom corners
    v0, w0 = np.array(v0), np.array(w0)
    approach = -(v0 + np.cross(w0, r))[:, 2]  # [m/s] towards the plane
    lam = np.maximum(approach, 0.0) / (split * _corner_response(r[:, 0], r[:, 1]))
    inertia = MASS * np.diag([HALF[1] ** 2 + HALF[2] ** 2, HALF[0] ** 2 + HALF[2] ** 2, HALF[0] ** 2 + HALF[1] ** 2]) / 3.0
    impulses = lam[:, None] * np.array([0.0, 0.0, 1.0])  # on the box, along -n
    v = v0 + impulses.sum(axis=0) / MASS
    w = w0 + np.linalg.solve(inertia, np.cross(r, impulses).sum(axis=0))

    got = buf.rows.lam.to_numpy()[:4]
    np.testing.assert_allclose(got[:, 0], lam, rtol=IMPULSE_RTOL, atol=1e-9 * MASS)
    np.testing.assert_array_equal(got[:, 1:], 0.0)
    if w0.any():
        assert (lam == 0.0).sum() == 2  # the turning box lifts two corners off: the projection acts
    np.testing.assert_allclose(buf.bodies.lin_vel[0].to_numpy(), v, rtol=IMPULSE_RTOL, atol=1e-7)
    np.testing.assert_allclose(buf.bodies.ang_vel[0].to_numpy(), w, rtol=IMPULSE_RTOL, atol=1e-6)
