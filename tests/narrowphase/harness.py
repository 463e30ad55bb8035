"""Test harness for the narrowphase: one polytope pool, one kernel, batches of shape pairs.

Every test of tests/narrowphase goes through ``Harness.run``: it writes a batch
of (a, b) shape poses into struct fields, runs ``collide`` on all of them in
ONE kernel launch and returns the manifolds as numpy. The pool holds every
polytope the tests need (``POLYTOPES``), built once per session, so the
collide kernel compiles once for the whole suite (about 25 s with the default
Taichi settings on this 2-core machine, about 2 s once Taichi's offline cache
holds it).

Also here: small pose builders and a brute-force numpy signed distance between
two convex polytopes, the reference for the hull tests.
"""


import math
from dataclasses import dataclass

import numpy as np

from sandbox.scene.rotations import quat_mul, quat_to_matrix  # noqa: F401  (the tests import them from here)
import taichi as ti

from sandbox.narrowphase import Manifold, ShapePose, collide
from sandbox.shapes import (BOX, CAPSULE, HULL, PLANE, SPHERE, TRIANGLE, PolytopePool, box_polytope,
                            hull_polytope, triangle_polytope)

BATCH_CAPACITY = 512


def _random_hull_points(seed: int, count: int, radii) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * np.asarray(radii) * rng.uniform(0.8, 1.0, size=(count, 1))


def _cylinder_points(segments: int, radius: float, half_height: float) -> np.ndarray:
    ang = 2 * np.pi * np.arange(segments) / segments
    ring = np.stack([radius * np.cos(ang), radius * np.sin(ang)], axis=1)
    return np.concatenate([np.c_[ring, -half_height * np.ones(segments)], np.c_[ring, half_height * np.ones(segments)]])


POLYTOPES = {
    "cube": box_polytope([0.5, 0.5, 0.5]),  # 1 m cube
    "small_cube": box_polytope([0.25, 0.25, 0.25]),
    "slab": box_polytope([2.0, 2.0, 0.5]),  # wide base for resting tests
    "tri_front": triangle_polytope([-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [2.0, 2.0, 0.0]),
    "tri_back": triangle_polytope([-2.0, -2.0, 0.0], [2.0, 2.0, 0.0], [-2.0, 2.0, 0.0]),
    "tet": hull_polytope([[0.0, 0.0, 0.6], [0.55, 0.0, -0.2], [-0.3, 0.45, -0.2], [-0.3, -0.45, -0.2]]),
    "tet2": hull_polytope([[0.1, 0.0, -0.5], [0.5, 0.3, 0.3], [-0.4, 0.35, 0.25], [-0.2, -0.5, 0.2]]),
    "rock": hull_polytope(_random_hull_points(7, 14, [0.6, 0.45, 0.35])),
    "pebble": hull_polytope(_random_hull_points(11, 20, [0.4, 0.4, 0.3])),
    "cylinder64": hull_polytope(_cylinder_points(32, 0.5, 0.3)),  # 64 vertices: the largest hull allowed
}


@dataclass
class Shape:
    kind: int
    pos: tuple = (0.0, 0.0, 0.0)
    rot: tuple = (1.0, 0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    radius: float = 0.0
    half_height: float = 0.0
    poly: str | None = None


def plane(normal=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0)) -> Shape:
    n = np.asarray(normal, dtype=float)
    return Shape(PLANE, pos=tuple(point), normal=tuple(n / np.linalg.norm(n)))


def sphere(pos, radius) -> Shape:
    return Shape(SPHERE, pos=tuple(pos), radius=radius)


def capsule(pos, rot, radius, half_height) -> Shape:
    return Shape(CAPSULE, pos=tuple(pos), rot=tuple(rot), radius=radius, half_height=half_height)


def polytope(name, pos=(0.0, 0.0, 0.0), rot=(1.0, 0.0, 0.0, 0.0)) -> Shape:
    kind = TRIANGLE if name.startswith("tri") else BOX if "cube" in name or name == "slab" else HULL
    return Shape(kind, pos=tuple(pos), rot=tuple(rot), poly=name)


def quat_axis_angle(axis, angle) -> np.ndarray:
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    return np.r_[math.cos(angle / 2), math.sin(angle / 2) * a]


def random_quat(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


@dataclass
class Contact:
    """One manifold as numpy: normal (3,), points (count, 3), separation (count,), feature (count,)."""

    count: int
    normal: np.ndarray
    points: np.ndarray
    separation: np.ndarray
    feature: np.ndarray


def assert_points(contact: Contact, expected_points, expected_seps, *, pos_tol: float, sep_tol: float) -> None:
    """Compare a manifold's points and separations with the expected ones as sets (the order
    is not part of the contract); each test file passes its own tolerances."""
    assert contact.count == len(expected_points)
    got = sorted(zip(contact.points.tolist(), contact.separation.tolist()))
    want = sorted(zip([list(p) for p in expected_points], expected_seps))
    for (gp, gs), (wp, ws) in zip(got, want):
        np.testing.assert_allclose(gp, wp, atol=pos_tol)
        assert abs(gs - ws) < sep_tol


@ti.kernel
def _collide_batch(pool: ti.template(), a: ti.template(), b: ti.template(), margin: ti.template(),
                   out: ti.template(), n: ti.i32):
    for i in range(n):
        out[i] = collide(pool, a[i], b[i], margin[i])


class Harness:
    """Owns the pool and the batch fields; ``run`` is one kernel launch."""

    def __init__(self):
        self.names = list(POLYTOPES)
        self.poly_id = {name: i for i, name in enumerate(self.names)}
        polys = [POLYTOPES[n] for n in self.names]
        self.pool = PolytopePool(*PolytopePool.sizes(polys))
        self.pool.upload(polys)
        self.a = ShapePose.field(shape=BATCH_CAPACITY)
        self.b = ShapePose.field(shape=BATCH_CAPACITY)
        self.margin = ti.field(ti.f32, shape=BATCH_CAPACITY)
        self.out = Manifold.field(shape=BATCH_CAPACITY)

    def _bound(self, s: Shape) -> float:
        if s.kind == PLANE:
            return math.inf
        if s.kind in (SPHERE, CAPSULE):
            return s.radius + s.half_height
        return float(np.linalg.norm(POLYTOPES[s.poly].vertices, axis=1).max())

    def _poses(self, shapes: list[Shape]) -> dict:
        n = BATCH_CAPACITY
        d = {
            "kind": np.zeros(n, np.int32), "pos": np.zeros((n, 3), np.float32),
            "rot": np.tile(np.array([1, 0, 0, 0], np.float32), (n, 1)), "normal": np.zeros((n, 3), np.float32),
            "radius": np.zeros(n, np.float32), "half_height": np.zeros(n, np.float32),
            "poly": np.zeros(n, np.int32), "bound": np.zeros(n, np.float32),
        }
        for i, s in enumerate(shapes):
            d["kind"][i] = s.kind
            d["pos"][i] = s.pos
            d["rot"][i] = np.asarray(s.rot) / np.linalg.norm(s.rot)
            d["normal"][i] = s.normal
            d["radius"][i] = s.radius
            d["half_height"][i] = s.half_height
            d["poly"][i] = self.poly_id[s.poly] if s.poly is not None else 0
            d["bound"][i] = self._bound(s)
        return d

    def run(self, pairs: list[tuple[Shape, Shape]], margin: float = 0.02) -> list[Contact]:
        """Collide every (a, b) pair with one kernel launch; margin in metres."""
        if len(pairs) > BATCH_CAPACITY:
            raise ValueError(f"at most {BATCH_CAPACITY} pairs per batch")
        self.a.from_numpy(self._poses([p[0] for p in pairs]))
        self.b.from_numpy(self._poses([p[1] for p in pairs]))
        self.margin.from_numpy(np.full(BATCH_CAPACITY, margin, np.float32))
        _collide_batch(self.pool, self.a, self.b, self.margin, self.out, len(pairs))
        raw = self.out.to_numpy()
        result = []
        for i in range(len(pairs)):
            c = int(raw["count"][i])
            result.append(Contact(c, raw["normal"][i].astype(float), raw["points"][i][:c].astype(float),
                                  raw["separation"][i][:c].astype(float), raw["feature"][i][:c].copy()))
        return result


# ---------------------------------------------------------------------------------------------
# brute-force reference in numpy (float64)


def world_polytope(name: str, pos, rot):
    """Vertices (V, 3), face normals (F, 3), face offsets (F,), edges (E, 2), loops of a placed polytope."""
    p = POLYTOPES[name]
    r = quat_to_matrix(np.asarray(rot) / np.linalg.norm(rot))
    v = p.vertices @ r.T + np.asarray(pos)
    n = p.face_normals @ r.T
    return v, n, np.einsum("ij,ij->i", n, v[[loop[0] for loop in p.face_loops]]), p.edges, p.face_loops


def _segment_distances(p1, q1, p2, q2) -> np.ndarray:
    """Distances between segment pairs (Ericson 5.1.9, vectorised; no degenerate segments)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    denom = a * e - b * b
    s = np.where(denom > 1e-14 * a * e, np.clip((b * f - c * e) / np.where(denom == 0, 1, denom), 0, 1), 0.0)
    t = (b * s + f) / e
    s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
    t = np.clip(t, 0, 1)
    return np.linalg.norm(p1 + d1 * s[:, None] - (p2 + d2 * t[:, None]), axis=1)


def _vertex_face_distances(verts, normals, offsets, loops, world_v) -> np.ndarray:
    """Distances from points to faces, only where the point projects inside the face (else inf)."""
    out = np.full(len(verts), np.inf)
    for n, off, loop in zip(normals, offsets, loops):
        h = verts @ n - off
        proj = verts - h[:, None] * n
        inside = np.ones(len(verts), bool)
        poly = world_v[loop]
        for k in range(len(poly)):
            e = poly[(k + 1) % len(poly)] - poly[k]
            inside &= (proj - poly[k]) @ np.cross(e, n) <= 0
        out = np.where(inside, np.minimum(out, np.abs(h)), out)
    return out


def polytope_sat(name_a, pos_a, rot_a, name_b, pos_b, rot_b) -> float:
    """Largest gap [m] over all face normals and edge-pair axes (no pruning).

    The exact signed distance when the shapes overlap (minus the penetration
    depth), a lower bound of the distance when they are apart.
    """
    va, na, oa, ea, _ = world_polytope(name_a, pos_a, rot_a)
    vb, nb, ob, eb, _ = world_polytope(name_b, pos_b, rot_b)
    gaps = [(vb @ na.T).min(axis=0) - oa, (va @ nb.T).min(axis=0) - ob]
    da = va[ea[:, 1]] - va[ea[:, 0]]
    db = vb[eb[:, 1]] - vb[eb[:, 0]]
    axes = np.cross(da[:, None, :], db[None, :, :]).reshape(-1, 3)
    ln = np.linalg.norm(axes, axis=1)
    axes = axes[ln > 1e-9] / ln[ln > 1e-9, None]
    pa, pb = axes @ va.T, axes @ vb.T
    gaps.append(np.maximum(pb.min(axis=1) - pa.max(axis=1), pa.min(axis=1) - pb.max(axis=1)))
    return float(max(g.max() for g in gaps))


def polytope_distance(name_a, pos_a, rot_a, name_b, pos_b, rot_b):
    """(sat, distance): the best SAT gap over all face and edge axes, and the Euclidean distance.

    sat is the exact signed distance when the shapes overlap (minus the
    penetration depth) and a lower bound when apart; distance is exact when
    apart (closest pair = vertex inside a face, or on two edges), 0 otherwise.
    """
    sat = polytope_sat(name_a, pos_a, rot_a, name_b, pos_b, rot_b)
    if sat <= 0:
        return sat, 0.0
    va, na, oa, ea, la = world_polytope(name_a, pos_a, rot_a)
    vb, nb, ob, eb, lb = world_polytope(name_b, pos_b, rot_b)
    ia, ib = np.meshgrid(np.arange(len(ea)), np.arange(len(eb)), indexing="ij")
    ia, ib = ia.ravel(), ib.ravel()
    dist = _segment_distances(va[ea[ia, 0]], va[ea[ia, 1]], vb[eb[ib, 0]], vb[eb[ib, 1]]).min()
    dist = min(dist, _vertex_face_distances(va, nb, ob, lb, vb).min(), _vertex_face_distances(vb, na, oa, la, va).min())
    return sat, dist


def place_touching(name_a, rot_a, name_b, rot_b, direction, iters: int = 40) -> np.ndarray:
    """Position of b (a at the origin) moved along ``direction`` until the two just touch."""
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    start = POLYTOPES[name_a].centroid @ quat_to_matrix(rot_a).T - POLYTOPES[name_b].centroid @ quat_to_matrix(rot_b).T
    lo, hi = 0.0, 10.0
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if polytope_sat(name_a, np.zeros(3), rot_a, name_b, start + mid * u, rot_b) < 0:
            lo = mid
        else:
            hi = mid
    return start + 0.5 * (lo + hi) * u


def _point_segment_distances(x, s0, s1) -> np.ndarray:
    """Distances from point x to segments (s0[i], s1[i])."""
    d = s1 - s0
    t = np.clip(np.einsum("ij,ij->i", x - s0, d) / np.einsum("ij,ij->i", d, d), 0, 1)
    return np.linalg.norm(s0 + d * t[:, None] - x, axis=1)


def core_polytope_distance(name, pos, rot, s0, s1) -> float:
    """Signed distance [m] between the segment [s0, s1] (a point when equal) and a placed polytope.

    Overlapping: the best gap over the Minkowski face normals (polytope faces and
    segment x edge), which is exact. Apart: the closest pair is an end point and
    a face interior, or the segment and an edge (segment-segment distance).
    """
    v, n, off, edges, loops = world_polytope(name, pos, rot)
    s0, s1 = np.asarray(s0, float), np.asarray(s1, float)
    seg = np.stack([s0, s1])
    gaps = [(seg @ n.T).min(axis=0) - off]
    d = s1 - s0
    if np.linalg.norm(d) > 1e-12:
        axes = np.cross(d, v[edges[:, 1]] - v[edges[:, 0]])
        ln = np.linalg.norm(axes, axis=1)
        axes = axes[ln > 1e-9] / ln[ln > 1e-9, None]
        ps, pv = axes @ seg.T, axes @ v.T
        gaps.append(np.maximum(ps.min(axis=1) - pv.max(axis=1), pv.min(axis=1) - ps.max(axis=1)))
    sat = max(g.max() for g in gaps)
    if sat <= 0:
        return sat
    e0, e1 = v[edges[:, 0]], v[edges[:, 1]]
    if np.linalg.norm(d) > 1e-12:
        dist = _segment_distances(np.tile(s0, (len(edges), 1)), np.tile(s1, (len(edges), 1)), e0, e1).min()
    else:
        dist = _point_segment_distances(s0, e0, e1).min()
    return min(dist, _vertex_face_distances(seg, n, off, loops, v).min())
