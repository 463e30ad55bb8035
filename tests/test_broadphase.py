"""The broadphase (sandbox/broadphase.py) on random boxes, against brute force.

Its own small buffers, no World: ~150 dynamic shapes (some bodies carry two, which must
never pair with each other), ~40 static shapes in the static grid, two planes. The pair
list must be exactly the brute-force set of overlapping bounds (closed intervals, the
device's own float32 bounds), each pair once, grouped by dynamic shape, the same on every
run; the bounds themselves are the rotated boxes grown by the margin and the step's motion.
With pair reuse (the enlarged bounds of ``Settings.pair_reuse_margin``), a search after some
bodies moved, in which only some shapes search again, must give the list of a full search over
the same bounds, in the same order.
"""

import numpy as np
import pytest

from sandbox.bodies import Bodies
from sandbox.awake import EVERY
from sandbox.broadphase import Broadphase, build_dynamic_grid, compute_all_aabbs
from sandbox.pair_search import SEARCH_ALL_REFITS, find_pairs
from sandbox.static_grid import build_static_grid
from sandbox.dispatch import PARALLEL, SERIAL
from sandbox.integrate import ErrorFlags
from sandbox.scene.rotations import quat_to_matrix
from sandbox.shapes import BOX, ShapeTable

SHAPES = 190
CAPACITY = 256
STATIC_HASH = 1024
MARGIN = 0.02  # [m]
DT = 1.0 / 60.0  # [s] bounds cover the motion over one step
CELL = 1.0  # [m] the dynamic grid's cell; boxes of up to 2.4 m span up to 4 cells per axis
AABB_TOLERANCE = 1e-5
"""[m] device (float32) against numpy (float64) bounds: coordinates below ~12 m have a float32
spacing of ~1e-6 m, and a bound is a few rounded products and sums."""
PLANES = {"normal": np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]], np.float32), "offset": np.array([-4.0, -3.0], np.float32)}


def _random_world(seed: int):
    """Host arrays of a random world: bodies (the last ones static) and their shapes."""
    rng = np.random.default_rng(seed)
    body_of_shape = np.sort(rng.integers(0, 160, SHAPES))  # a few bodies get two or more shapes
    bodies = int(body_of_shape.max()) + 1
    static_body = np.zeros(bodies, bool)
    static_body[rng.choice(bodies, 30, replace=False)] = True
    q = rng.normal(size=(bodies, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    body = {
        "inv_mass": np.where(static_body, 0.0, 1.0).astype(np.float32),
        "inertia": np.tile(np.eye(3, dtype=np.float32), (bodies, 1, 1)),
        "inv_inertia": np.tile(np.eye(3, dtype=np.float32), (bodies, 1, 1)) * (~static_body)[:, None, None],
        "pos": rng.uniform(-6.0, 6.0, (bodies, 3)),
        "rot": q,
        "lin_vel": rng.normal(0.0, 3.0, (bodies, 3)) * (~static_body)[:, None],
        "ang_vel": rng.normal(0.0, 2.0, (bodies, 3)) * (~static_body)[:, None],
    }
    half = rng.uniform(0.05, 1.2, (SHAPES, 3))
    local_q = rng.normal(size=(SHAPES, 4))
    local_q /= np.linalg.norm(local_q, axis=1, keepdims=True)
    shape = {
        "kind": np.full(SHAPES, BOX, np.int32),
        "body": body_of_shape.astype(np.int32),
        "local_pos": rng.uniform(-0.5, 0.5, (SHAPES, 3)).astype(np.float32),
        "local_rot": local_q.astype(np.float32),
        "aabb_center": rng.uniform(-0.1, 0.1, (SHAPES, 3)).astype(np.float32),
        "aabb_half": half.astype(np.float32),
        "bound": np.linalg.norm(half, axis=1).astype(np.float32) + 0.15,  # covers the offset centre too
    }
    dynamic = np.flatnonzero(~static_body[body_of_shape]).astype(np.int32)
    static = np.flatnonzero(static_body[body_of_shape])
    return body, shape, dynamic, static


def _expected_aabbs(body, shape, swept):
    """numpy: the rotated box of each shape, grown by the margin and (``swept``) its motion."""
    lo, hi = np.zeros((SHAPES, 3)), np.zeros((SHAPES, 3))
    for i in range(SHAPES):
        b = shape["body"][i]
        rb = quat_to_matrix(body["rot"][b].astype(np.float32))
        r = rb @ quat_to_matrix(shape["local_rot"][i])
        centre = body["pos"][b] + rb @ shape["local_pos"][i] + r @ shape["aabb_center"][i]
        grow = MARGIN
        if swept and body["inv_mass"][b] > 0:
            reach = np.linalg.norm(shape["local_pos"][i]) + shape["bound"][i]
            grow += DT * (np.linalg.norm(body["lin_vel"][b]) + np.linalg.norm(body["ang_vel"][b]) * reach)
        ext = np.abs(r) @ shape["aabb_half"][i] + grow
        lo[i], hi[i] = centre - ext, centre + ext
    return lo, hi


def _brute_force_pairs(lo, hi, shape, dynamic, static):
    """Every (dynamic i, partner) whose closed bounds overlap: dynamic partners j > i of
    another body, every static shape, planes as -1 - p when the box reaches below it."""
    pairs = []
    dyn = set(dynamic.tolist())
    for i in dynamic:
        for j in range(SHAPES):
            if j in dyn and (j <= i or shape["body"][j] == shape["body"][i]):
                continue
            if np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i]):
                pairs.append((int(i), j))
        centre, half = 0.5 * (lo[i] + hi[i]), 0.5 * (hi[i] - lo[i])
        for p, (n, offset) in enumerate(zip(PLANES["normal"], PLANES["offset"])):
            if n @ centre - np.abs(n) @ half <= offset:
                pairs.append((int(i), -1 - p))
    return pairs


class _Broadphase:
    """One random world in its own buffers, its static grid built from the device's bounds."""

    def __init__(self, seed: int):
        self.body, self.shape, self.dynamic, self.static = _random_world(seed)
        self.bodies = Bodies(CAPACITY)
        self.bodies.upload(self.body)
        self.shapes = ShapeTable(CAPACITY, 8)
        planes = dict(PLANES, body=np.zeros(2, np.int32), friction=np.zeros(2, np.float32),
                      restitution=np.zeros(2, np.float32))
        self.shapes.upload(self.shape, planes, self.dynamic)
        self.bp = Broadphase(CAPACITY, 8192, 4096, STATIC_HASH, 4096)
        self.errors = ErrorFlags()
        self.errors.clear()
        compute_all_aabbs(self.bp, self.shapes, self.bodies, MARGIN)
        lo, hi = self._aabbs()
        self.grid = build_static_grid(lo, hi, self.static, CELL, hash_size=STATIC_HASH)
        self.bp.upload_static_grid(self.grid)
        self.bp.cell_size[None] = CELL

    def _aabbs(self):
        n = SHAPES
        return self.bp.aabb_min.to_numpy()[:n].astype(np.float64), self.bp.aabb_max.to_numpy()[:n].astype(np.float64)

    def pairs(self, dispatch=PARALLEL, reuse_margin=0.0, full=True):
        """The pair list after a grid build and a pair search; ``full``: every shape searches and
        is refitted (as in a new world), else only those the reuse rules pick."""
        if full:
            self.bp.listed[None] = 0
        build_dynamic_grid(self.bp, self.shapes, self.bodies, MARGIN, reuse_margin, DT, 0.0, self.errors, EVERY,
                           dispatch)
        find_pairs(self.bp, self.shapes, EVERY, dispatch)
        total = int(self.bp.pair_total[None])
        a, b = self.bp.pair_a.to_numpy()[:total], self.bp.pair_b.to_numpy()[:total]
        return list(zip(a.tolist(), b.tolist()))


@pytest.fixture(scope="module")
def world():
    return _Broadphase(seed=11)


def test_bounds_are_the_rotated_boxes_grown_by_margin_and_motion(world):
    static_lo, static_hi = world._aabbs()  # from compute_all_aabbs: no motion
    lo, hi = _expected_aabbs(world.body, world.shape, swept=False)
    np.testing.assert_allclose(static_lo, lo, rtol=0, atol=AABB_TOLERANCE)
    np.testing.assert_allclose(static_hi, hi, rtol=0, atol=AABB_TOLERANCE)
    world.pairs()  # the dynamic grid rewrites the dynamic shapes' bounds, swept over the step
    lo, hi = _expected_aabbs(world.body, world.shape, swept=True)
    got_lo, got_hi = world._aabbs()
    np.testing.assert_allclose(got_lo[world.dynamic], lo[world.dynamic], rtol=0, atol=AABB_TOLERANCE)
    np.testing.assert_allclose(got_hi[world.dynamic], hi[world.dynamic], rtol=0, atol=AABB_TOLERANCE)
    assert int(world.errors.flags[None]) == 0


def test_pairs_are_the_brute_force_overlaps_each_once(world):
    pairs = world.pairs()
    lo, hi = world._aabbs()
    expected = _brute_force_pairs(lo, hi, world.shape, world.dynamic, world.static)
    assert len(pairs) == len(set(pairs)), "a pair is listed twice"
    assert set(pairs) == set(expected)
    # the random world exercises every kind of partner
    kinds = {("static" if b in set(world.static.tolist()) else "dynamic") if b >= 0 else "plane" for _, b in pairs}
    assert kinds == {"dynamic", "static", "plane"}
    assert len(pairs) > 100


def test_pairs_come_grouped_by_dynamic_shape_in_a_fixed_order(world):
    first = world.pairs()
    order = {int(i): k for k, i in enumerate(world.dynamic)}
    slots = [order[a] for a, _ in first]
    assert slots == sorted(slots)  # each shape's pairs are contiguous, shapes in dynamic order
    for _ in range(3):
        assert world.pairs() == first  # the grid's fills run in thread order; the result does not


def test_pairs_are_the_same_whether_the_heavy_loops_run_serially_or_in_parallel(world):
    assert world.pairs(SERIAL) == world.pairs(PARALLEL)  # dispatch.py: the same list, in the same order


def _partner_order(j: int) -> tuple:
    """Shapes by id, then planes (partner -1 - p) by index."""
    return (0, j) if j >= 0 else (1, -1 - j)


def test_each_shape_lists_its_partners_by_id(world):
    pairs = world.pairs()
    by_shape = {}
    for a, b in pairs:
        by_shape.setdefault(a, []).append(b)
    assert all(part == sorted(part, key=_partner_order) for part in by_shape.values())


REUSE = 0.05  # [m] the enlarged bounds' growth in the reuse tests


def _move_some_bodies(world, rng, far: int, near: int):
    """Shift ``far`` dynamic bodies by 0.5 m (out of their enlarged bounds) and ``near`` by
    2 mm (inside them), and upload the bodies again; returns the shifted ones."""
    dynamic_bodies = np.unique(world.shape["body"][world.dynamic])
    chosen = rng.choice(dynamic_bodies, far + near, replace=False)
    pos = world.body["pos"].copy()
    pos[chosen[:far]] += rng.choice([-0.5, 0.5], (far, 3))
    pos[chosen[far:]] += rng.choice([-0.002, 0.002], (near, 3))
    world.body = dict(world.body, pos=pos)
    world.bodies.upload(world.body)
    return chosen


def test_enlarged_bounds_contain_the_step_bounds_and_are_kept_while_they_do():
    w = _Broadphase(seed=5)
    w.pairs(reuse_margin=REUSE)
    lo, hi = _expected_aabbs(w.body, w.shape, swept=True)
    grow = np.minimum(REUSE, 0.25 * w.shape["bound"])[:, None]
    fat_lo, fat_hi = w._aabbs()
    d = w.dynamic
    np.testing.assert_allclose(fat_lo[d], (lo - grow)[d], rtol=0, atol=AABB_TOLERANCE)
    np.testing.assert_allclose(fat_hi[d], (hi + grow)[d], rtol=0, atol=AABB_TOLERANCE)
    moved = _move_some_bodies(w, np.random.default_rng(1), far=0, near=12)
    w.pairs(reuse_margin=REUSE, full=False)
    assert int(w.bp.searched[None]) == 0  # 2 mm is inside every enlarged bound: no shape searched
    kept_lo, kept_hi = w._aabbs()
    np.testing.assert_array_equal(kept_lo, fat_lo)
    np.testing.assert_array_equal(kept_hi, fat_hi)
    lo, hi = _expected_aabbs(w.body, w.shape, swept=True)
    assert np.all(kept_lo[d] <= lo[d] + AABB_TOLERANCE) and np.all(hi[d] <= kept_hi[d] + AABB_TOLERANCE)
    assert len(moved) == 12


def _grid(bp) -> dict:
    """The dynamic grid as a pair search reads it."""
    n = int(bp.entry_total[None])
    out = {"entry_total": n, "bucket_start": bp.bucket_start.to_numpy()}
    for name in ("sorted_shape", "sorted_lo", "sorted_hi", "sorted_body", "sorted_cell_lo"):
        out[name] = getattr(bp, name).to_numpy()[:n]
    return out


def test_a_grid_whose_shapes_all_keep_their_bounds_is_kept_and_equals_a_rebuild():
    """A step in which no shape refits its enlarged bounds (a settled pile) skips the grid's build,
    and the grid it keeps is the one a build from the same bounds makes."""
    w = _Broadphase(seed=7)
    w.pairs(reuse_margin=REUSE)
    built = _grid(w.bp)
    _move_some_bodies(w, np.random.default_rng(7), far=0, near=12)  # 2 mm: inside every enlarged bound
    w.bp.bucket_fill.fill(-7)  # a build clears it and counts into it
    kept_pairs = w.pairs(reuse_margin=REUSE, full=False)
    assert int(w.bp.refitted.to_numpy()[:SHAPES].sum()) == 0 and int(w.bp.searched[None]) == 0
    assert np.all(w.bp.bucket_fill.to_numpy() == -7), "the grid was built though no shape refitted"
    kept = _grid(w.bp)
    w.bp.refits[None] = 1  # force the build, from the same bounds
    assert w.pairs(reuse_margin=REUSE, full=False) == kept_pairs
    assert not np.all(w.bp.bucket_fill.to_numpy() == -7)
    rebuilt = _grid(w.bp)
    for name in built:
        np.testing.assert_array_equal(kept[name], built[name], err_msg=name)
        np.testing.assert_array_equal(rebuilt[name], built[name], err_msg=name)


@pytest.mark.parametrize("seed", [2, 3])
def test_a_search_of_some_shapes_lists_what_a_full_search_of_the_same_bounds_lists(seed):
    w = _Broadphase(seed=seed)
    w.pairs(reuse_margin=REUSE)
    _move_some_bodies(w, np.random.default_rng(seed), far=8, near=20)
    kept = w.pairs(reuse_margin=REUSE, full=False)
    searched = int(w.bp.searched[None])
    assert 0 < searched < len(w.dynamic) // 2  # most shapes copied their old list
    lo, hi = w._aabbs()  # the enlarged bounds this search used
    expected = _brute_force_pairs(lo, hi, w.shape, w.dynamic, w.static)
    order = {int(i): k for k, i in enumerate(w.dynamic)}
    # the full search's order: shapes in slot order, each shape's partners by id
    assert kept == sorted(expected, key=lambda p: (order[p[0]], _partner_order(p[1])))
    for dispatch in (SERIAL, PARALLEL):  # and searching again from these bounds changes nothing
        assert w.pairs(dispatch, reuse_margin=REUSE, full=False) == kept


def test_when_many_shapes_refit_every_shape_searches_and_lists_what_a_full_search_lists():
    """More than one shape in SEARCH_ALL_REFITS refitted (a landing pile): every shape searches
    instead of each refitted one marking its partners of lower id, and the list is the same."""
    w = _Broadphase(seed=3)
    before = w.pairs(reuse_margin=REUSE)
    _move_some_bodies(w, np.random.default_rng(3), far=60, near=0)
    kept = w.pairs(reuse_margin=REUSE, full=False)
    refitted = w.bp.refitted.to_numpy()
    assert SEARCH_ALL_REFITS * int(refitted[w.dynamic].sum()) > len(w.dynamic)
    # below the share, a shape searches when it or a partner (last step's or this step's) refitted:
    # some would have kept their lists, so only the switch makes every shape search
    touched = {int(i) for i in w.dynamic if refitted[i]} | {i for i, j in before + kept if j >= 0 and refitted[j]}
    assert len(touched) < len(w.dynamic)
    assert int(w.bp.searched[None]) == len(w.dynamic)
    assert int(w.bp.refits[None]) == 0  # the search clears the count for the next step
    lo, hi = w._aabbs()
    expected = _brute_force_pairs(lo, hi, w.shape, w.dynamic, w.static)
    order = {int(i): k for k, i in enumerate(w.dynamic)}
    assert kept == sorted(expected, key=lambda p: (order[p[0]], _partner_order(p[1])))


def test_static_grid_lists_each_static_shape_in_every_cell_it_covers(world):
    """Built on the host with numpy: a cell's bucket holds every static shape whose bounds
    cover it (a bucket may hold more: several cells hash to it)."""
    grid = world.grid
    lo, hi = world._aabbs()
    start, entries, cell, size = grid["bucket_start"], grid["entries"], grid["cell_size"], grid["hash_size"]
    assert size == STATIC_HASH and start[-1] == len(entries)
    covered = 0
    for j in world.static:
        a, b = np.floor(lo[j] / cell).astype(int), np.floor(hi[j] / cell).astype(int)
        for x in range(a[0], b[0] + 1):
            for y in range(a[1], b[1] + 1):
                for z in range(a[2], b[2] + 1):
                    with np.errstate(over="ignore"):
                        c = np.array([x, y, z], np.int32)
                        h = int(((c[0] * np.int32(73856093)) ^ (c[1] * np.int32(19349663))
                                 ^ (c[2] * np.int32(83492791))) & np.int32(size - 1))
                    assert j in entries[start[h]:start[h + 1]], f"static shape {j} missing from cell {(x, y, z)}"
                    covered += 1
    assert covered == len(entries)  # and nothing else: one entry per (shape, cell)
    for h in range(size):  # each bucket in shape order (the lexsort), so runs repeat exactly
        assert np.all(np.diff(entries[start[h]:start[h + 1]]) >= 0)


def test_static_grid_of_no_statics_is_empty():
    grid = build_static_grid(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int64), CELL)
    assert grid["bucket_start"].sum() == 0 and len(grid["entries"]) == 0
    assert np.all(np.asarray(grid["lo"]) > np.asarray(grid["hi"]))  # empty bounds: nothing is visited


@pytest.mark.parametrize("scene, steps", [("dominoes", 200), ("projectile_wall", 120)])
def test_a_world_steps_to_the_same_bits_whatever_its_pair_reuse_margin(scene, steps):
    """The enlarged bounds change which shapes search and which pairs without points are
    listed, never which contacts a step has nor their order (Settings.pair_reuse_margin names
    the one exception, far speculative points; these scenes have none)."""
    from sandbox import Scene, World
    from sandbox.scene.library import resolve_scene

    from .helpers import TEST_ARCH

    states = []
    for margin in (0.0, 0.1):
        w = World(Scene.load(resolve_scene(scene)), arch=TEST_ARCH)
        w.settings = w.settings.replace(pair_reuse_margin=margin)
        w.step(steps)
        s = w.state()
        states.append(np.concatenate([np.ascontiguousarray(s[k], np.float32).ravel() for k in
                                      ("position", "orientation", "linear_velocity", "angular_velocity")]))
    np.testing.assert_array_equal(states[0].view(np.uint32), states[1].view(np.uint32))
