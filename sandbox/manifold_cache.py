"""Manifold reuse: a shape pair that has barely moved relative to itself keeps its
contact points instead of running SAT and clipping again (Jolt's body pair cache,
``ContactConstraintManager``'s ``mBodyPairCache``).

A settled pile is almost all resting pairs, and for them the narrowphase recomputes
the same manifold every step. So every manifold found is remembered with the pose
of shape b in shape a's frame at that moment, its normal in a's frame, and each
point as two anchors, the point on a's surface in a's frame and the point on b's
surface in b's frame. Next step, a pair whose relative pose is still within
``Settings.manifold_reuse_distance`` and ``manifold_reuse_angle`` of that
remembered pose takes the manifold back: the anchors ride with their bodies, the
normal with the shape whose face it is (``Manifold.normal_on_b``: a plank leaning on
the ground keeps the ground's normal, not one tilting with the plank, which would turn
part of the support into a sideways push), and the separation is measured again along it, so depth and its
rate stay exact for the contact points kept; what reuse skips is only finding new
points (a point appearing or clipping moving), which needs more relative motion
than the tolerance. The remembered pose is the one the manifold was found at, not
last step's, so reuse never drifts further than the tolerance. Feature ids are kept,
so warm starting matches exactly.

A body put in the world overlapping another (placed so by the scene, dropped or fractured into
it: deeper than a loaded contact rests, ``overlap_depth``, when the first narrowphase after its
placement finds the pair) marks that pair ``overlap`` until it comes out to that depth; the mark
rides with the pair from step to step (``carry_overlap``), and its rows push out no faster than
``Settings.overlap_push_speed`` (solvers/normal_target.py, bias_push). Contacts that arrive as gaps and
are pressed in by an impact or a load are never marked, nor those a rebuilt world (an edit, grown
buffers, a restored good state) finds again, but for the marked ones, whose bodies count as placed
again (edits.Edits.keep_overlaps): their depth is the springs' physics.

A pair with no points is skipped too while a bound says it still cannot touch: the
narrowphase reports a lower bound of the distance (``Manifold.gap``: SAT's separation,
or the bounding spheres'), and relative motion brings any point of b at most its
origin's displacement plus its bound times the turn closer (``find_reusable``). That
one is exact, not a tolerance.

Storage is double-buffered by pair slot (``parity`` says which half is this step's),
and each dynamic shape's pairs are one contiguous range, as in the broadphase's pair
list, so the lookup is a short scan of the shape's old pairs. No atomics but an
integer count: deterministic.
"""

import taichi as ti

from .awake import shape_id, shape_total
from .backend import serialize_light_loops
from .math3d import dot, norm, quat_conj, quat_mul, quat_rotate, quat_rotate_inv
from .narrowphase.manifold import MAX_POINTS, Manifold, ShapePose, manifold_point, relative_pose

vec3 = ti.math.vec3
vec4 = ti.math.vec4

OVERLAP_DEFLECTIONS = 2.0
"""A pair is overlapping when deeper than its slop plus this many ``contact_deflection``s of its
bound: a loaded contact rests within one (the spring is stiffened to hold its load there), so a
new world built from a resting stack's poses, whose bodies are all placed, marks none of its
contacts (a landing pile pressed deeper may have some)."""


def overlap_depth(settings) -> float:
    """[1] The depth beyond the slop, as a fraction of a pair's smaller bound, past which a new
    pair is marked overlapping (OVERLAP_DEFLECTIONS)."""
    return OVERLAP_DEFLECTIONS * settings.contact_deflection


@ti.data_oriented
class ManifoldCache:
    def __init__(self, pair_capacity: int, shape_capacity: int):
        pc = max(16, pair_capacity)
        sc = max(1, shape_capacity)
        self.parity = ti.field(ti.i32, ())  # which half holds the pairs being written this step
        self.reused = ti.field(ti.i32, ())  # manifolds (pairs with points) taken back, last narrowphase
        self.reused_pairs = ti.field(ti.i32, ())  # pairs not searched again, with or without points
        self.partner = ti.field(ti.i32, (2, pc))
        self.count = ti.field(ti.i32, (2, pc))
        self.gap = ti.field(ti.f32, (2, pc))  # no points: a lower bound of the distance when found [m]
        self.rel_pos = ti.Vector.field(3, ti.f32, (2, pc))  # b's origin in a's frame when found [m]
        self.rel_rot = ti.Vector.field(4, ti.f32, (2, pc))  # b's orientation in a's frame when found
        self.normal = ti.Vector.field(3, ti.f32, (2, pc))  # in the frame of the shape whose face it is
        self.normal_on_b = ti.field(ti.i32, (2, pc))  # that shape is b (else a)
        self.overlap = ti.field(ti.i32, (2, pc))  # 1: found overlapping and not yet out (carry_overlap)
        self.on_a = ti.Vector.field(3, ti.f32, (2, pc * MAX_POINTS))  # a's surface point, a's frame [m]
        self.on_b = ti.Vector.field(3, ti.f32, (2, pc * MAX_POINTS))  # b's surface point, b's frame [m]
        self.feature = ti.field(ti.i32, (2, pc * MAX_POINTS))
        self.first = ti.field(ti.i32, (2, sc))  # a dynamic shape's pairs: [first, last) of its half
        self.last = ti.field(ti.i32, (2, sc))


@ti.func
def clear_cache_loops(cache: ti.template()):
    """Forget every manifold (a new world, or a state the remembered ones do not belong to)."""
    cache.parity[None] = 0
    cache.reused[None] = 0
    cache.reused_pairs[None] = 0
    for h, i in cache.first:
        cache.first[h, i] = 0
        cache.last[h, i] = 0


@ti.kernel
def clear_cache(cache: ti.template()):
    clear_cache_loops(cache)


@ti.func
def start_step(cache: ti.template()):
    """Zero the reuse counters before a narrowphase (close_step ends it)."""
    cache.reused[None] = 0
    cache.reused_pairs[None] = 0


@ti.func
def old_slot(cache: ti.template(), i: ti.i32, j: ti.i32) -> ti.i32:
    """Slot of pair (i, j) in last step's half, -1 when the pair is new."""
    old = 1 - cache.parity[None]
    found = -1
    for o in range(cache.first[old, i], cache.last[old, i]):
        if found < 0 and cache.partner[old, o] == j:
            found = o
    return found


@ti.func
def find_reusable(cache: ti.template(), found: ti.i32, a: ShapePose, b: ShapePose, margin: ti.f32,
                  max_d2: ti.f32, max_sin_half: ti.f32) -> ti.i32:
    """``found`` (old_slot) if the manifold there can stand for a new one, else -1.

    With points: the pair's relative pose is still within the tolerance of the one they were
    found at. Without: the shapes were at least ``gap`` apart then, and since then no point of
    b has come closer to a than b's origin moved plus its bound times 2 sin(half the turn),
    so they are still farther apart than ``margin``: exactly the answer a new search would
    give, whatever the tolerance (padded for the float32 rounding of the poses).

    The turn is measured as sin(half angle) = |vector part of q_old* q_now|, which float32
    resolves down to ~1e-7 rad; 1 - |q_old . q_now| (its cosine) rounds to 0 below ~5e-4 rad."""
    old = 1 - cache.parity[None]
    slot = -1
    if found >= 0 and max_d2 > 0.0:
        p_ba, q_ba = relative_pose(a, b)
        moved2 = (p_ba - cache.rel_pos[old, found]).norm_sqr()
        d = quat_mul(quat_conj(cache.rel_rot[old, found]), q_ba)
        sin_half = norm(vec3(d[1], d[2], d[3])) / d.norm()  # either sign of q
        if cache.count[old, found] > 0:
            if moved2 < max_d2 and sin_half < max_sin_half:
                slot = found
        elif cache.gap[old, found] > 0.0:
            rounding = 1e-6 * (norm(a.pos) + norm(p_ba) + b.bound)
            closer = ti.sqrt(moved2) + 2.0 * sin_half * b.bound * (1.0 + 1e-3) + rounding
            if cache.gap[old, found] - closer > margin:
                slot = found
    return slot


@ti.func
def reuse_manifold(cache: ti.template(), o: ti.i32, p: ti.i32, a: ShapePose, b: ShapePose) -> Manifold:
    """Last step's manifold in slot o at the shapes' current poses (no points stays no
    points); carried to slot p and counted."""
    old = 1 - cache.parity[None]
    cur = cache.parity[None]
    on_b = cache.normal_on_b[old, o]
    n = quat_rotate(b.rot if on_b else a.rot, cache.normal[old, o])
    m = Manifold(count=cache.count[old, o], normal=n)
    for k in range(m.count):
        so = MAX_POINTS * o + k
        ra = quat_rotate(a.rot, cache.on_a[old, so])
        gap = (b.pos - a.pos) + quat_rotate(b.rot, cache.on_b[old, so]) - ra  # differences first: float32 at 20 m
        mid = a.pos + ra + 0.5 * gap
        for c in ti.static(range(3)):
            m.points[k, c] = mid[c]
        m.separation[k] = dot(n, gap)
        m.feature[k] = cache.feature[old, so]
        sp = MAX_POINTS * p + k
        cache.on_a[cur, sp] = cache.on_a[old, so]
        cache.on_b[cur, sp] = cache.on_b[old, so]
        cache.feature[cur, sp] = cache.feature[old, so]
    cache.partner[cur, p] = cache.partner[old, o]
    cache.count[cur, p] = m.count
    cache.gap[cur, p] = cache.gap[old, o]
    cache.rel_pos[cur, p] = cache.rel_pos[old, o]  # the pose it was found at, so reuse cannot drift
    cache.rel_rot[cur, p] = cache.rel_rot[old, o]
    cache.normal[cur, p] = cache.normal[old, o]
    cache.normal_on_b[cur, p] = on_b
    ti.atomic_add(cache.reused_pairs[None], 1)  # integer counts: the order of adds does not matter
    if m.count > 0:
        ti.atomic_add(cache.reused[None], 1)
    return m


@ti.func
def remember_manifold(cache: ti.template(), p: ti.i32, j: ti.i32, m: Manifold, a: ShapePose, b: ShapePose):
    """Keep a freshly found manifold of pair slot p (partner j) for the next step."""
    cur = cache.parity[None]
    p_ba, q_ba = relative_pose(a, b)
    cache.partner[cur, p] = j
    cache.count[cur, p] = m.count
    cache.gap[cur, p] = m.gap
    cache.rel_pos[cur, p] = p_ba
    cache.rel_rot[cur, p] = q_ba
    cache.normal[cur, p] = quat_rotate_inv(b.rot if m.normal_on_b else a.rot, m.normal)
    cache.normal_on_b[cur, p] = m.normal_on_b
    for k in range(m.count):
        x = manifold_point(m, k)
        half = 0.5 * m.separation[k] * m.normal
        sp = MAX_POINTS * p + k
        cache.on_a[cur, sp] = quat_rotate_inv(a.rot, x - half - a.pos)
        cache.on_b[cur, sp] = quat_rotate_inv(b.rot, x + half - b.pos)
        cache.feature[cur, sp] = m.feature[k]


@ti.func
def carry_overlap(cache: ti.template(), p: ti.i32, found: ti.i32, placed: ti.i32, m: Manifold, depth: ti.f32):
    """Pair slot p's overlap mark (module docstring), stored in this step's half: set
    when the pair is new (``found`` < 0), one of its bodies was just ``placed``
    (bodies.Bodies.mark_placed) and a point lies deeper than ``depth`` [m]; kept while one still
    does, and once cleared never set again for the pair's life."""
    deep = 0
    for k in range(m.count):
        if m.separation[k] < -depth:
            deep = 1
    marked = placed
    if found >= 0:
        marked = cache.overlap[1 - cache.parity[None], found]
    cache.overlap[cache.parity[None], p] = marked * deep


@ti.func
def close_step(cache: ti.template(), bp: ti.template(), shapes: ti.template(), n_pairs: ti.i32, awake: ti.template()):
    """Record each dynamic shape's range of pair slots in this step's half, then hand the
    halves over: what was written becomes what the next step reads. ``awake`` (awake.py):
    the shapes that enumerated pairs; a sleeping shape's manifolds wait in sleep.py's store."""
    cur = cache.parity[None]
    n = shape_total(shapes, awake)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shape_id(shapes, awake, k)
        cache.first[cur, i] = ti.min(bp.pair_start[k], n_pairs)
        cache.last[cur, i] = ti.min(bp.pair_start[k + 1], n_pairs)
    cache.parity[None] = 1 - cur
