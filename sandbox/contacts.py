"""The contact buffer: one record per contact point, shared by every solver, and the
stage that fills it (narrowphase over the broadphase pairs, then compaction).

Normal convention, stated once for the whole engine: ``normal`` points from body
``a`` to body ``b``; ``a`` is always the dynamic shape that enumerated the pair,
``b`` its partner (dynamic, static or a plane). Separation < 0 is penetration.

Layout: the narrowphase writes at most 4 points per pair into fixed slots
``4 * pair + k``; a scan over the per-pair counts then packs them, so points of
one pair are contiguous (a *manifold*, the block of block mass splitting) and
their order is that of the pair list: deterministic, with no atomics.
"""


import taichi as ti

from .awake import note_touch, shape_id, shape_total
from .backend import serialize_light_loops
from .math3d import dot, quat_mul, quat_rotate
from .narrowphase import collide_kinds
from .lanes import lane_capacity
from .narrowphase.manifold import MAX_POINTS, Manifold, ShapePose
from .broadphase import swept_distance
from .manifold_cache import (carry_overlap, close_step, find_reusable, old_slot, remember_manifold, reuse_manifold,
                             start_step)
from .prefix_sum import Scanner, exclusive_scan
from .shapes import PLANE

vec3 = ti.math.vec3
vec4 = ti.math.vec4
INF = 3.0e38


SLOP_FRACTION = 0.02
"""[1] A pair's slop is at most this fraction of its smaller shape's bounding radius: what a contact
tolerates scales with the body (at a tenth, 1 mm cubes rested 9 % into each other before any
correction)."""


@ti.data_oriented
class Contacts:
    def __init__(self, pair_capacity: int, shape_capacity: int):
        pc = max(16, pair_capacity)
        cc = lane_capacity(pc * MAX_POINTS)  # whole groups for the lane sweep (lanes.py)
        sc = max(1, shape_capacity)
        self.pair_capacity = pc
        self.capacity = cc
        # per pair, raw narrowphase output
        self.raw_count = ti.field(ti.i32, pc + 1)
        self.raw_normal = ti.Vector.field(3, ti.f32, pc)
        self.raw_point = ti.Vector.field(3, ti.f32, cc)
        self.raw_sep = ti.field(ti.f32, cc)
        self.raw_feature = ti.field(ti.i32, cc)
        self.has_points = ti.field(ti.i32, pc + 1)
        self.raw_slop = ti.field(ti.f32, pc)
        self.raw_size = ti.field(ti.f32, pc)
        self.point_start = ti.field(ti.i32, pc + 1)
        self.manifold_index = ti.field(ti.i32, pc + 1)
        self.count = ti.field(ti.i32, ())
        self.manifold_count = ti.field(ti.i32, ())
        self.scanner = Scanner(pc + 1)
        # per point
        self.body_a = ti.field(ti.i32, cc)
        self.body_b = ti.field(ti.i32, cc)
        self.shape_a = ti.field(ti.i32, cc)
        self.partner = ti.field(ti.i32, cc)
        self.feature = ti.field(ti.i32, cc)
        self.manifold = ti.field(ti.i32, cc)
        self.normal = ti.Vector.field(3, ti.f32, cc)
        self.point = ti.Vector.field(3, ti.f32, cc)
        self.sep = ti.field(ti.f32, cc)
        self.friction = ti.field(ti.f32, cc)
        self.restitution = ti.field(ti.f32, cc)
        self.slop = ti.field(ti.f32, cc)  # [m] the pair's tolerated penetration
        self.size = ti.field(ti.f32, cc)  # [m] the pair's smaller bounding radius (contact_deflection)
        self.overlap = ti.field(ti.i32, cc)  # 1: the pair was found overlapping and is not yet out (manifold_cache.py)
        # per manifold (= per touching shape pair): the block of block mass splitting
        self.m_body_a = ti.field(ti.i32, pc)
        self.m_body_b = ti.field(ti.i32, pc)
        self.m_start = ti.field(ti.i32, pc)
        self.m_count = ti.field(ti.i32, pc)
        # per shape: its points are contiguous, [shape_first, shape_last)
        self.shape_first = ti.field(ti.i32, sc)
        self.shape_last = ti.field(ti.i32, sc)


@ti.func
def shape_pose(shapes: ti.template(), bodies: ti.template(), i: ti.i32) -> ShapePose:
    b = shapes.body[i]
    q = bodies.rot[b]
    return ShapePose(
        kind=shapes.kind[i],
        pos=bodies.pos[b] + quat_rotate(q, shapes.local_pos[i]),
        rot=quat_mul(q, shapes.local_rot[i]),
        normal=vec3(0.0, 0.0, 1.0),
        radius=shapes.radius[i],
        half_height=shapes.half_height[i],
        poly=shapes.poly[i],
        bound=shapes.bound[i],
    )


@ti.func
def plane_pose(shapes: ti.template(), p: ti.i32) -> ShapePose:
    n = shapes.plane_normal[p]
    return ShapePose(
        kind=PLANE,
        pos=n * shapes.plane_offset[p],
        rot=vec4(1.0, 0.0, 0.0, 0.0),
        normal=n,
        radius=0.0,
        half_height=0.0,
        poly=-1,
        bound=INF,
    )


@ti.func
def partner_body(shapes: ti.template(), partner: ti.i32) -> ti.i32:
    b = 0
    if partner < 0:
        b = shapes.plane_body[-1 - partner]
    else:
        b = shapes.body[partner]
    return b


@ti.func
def partner_material(shapes: ti.template(), partner: ti.i32):
    f, e = 0.0, 0.0
    if partner < 0:
        f = shapes.plane_friction[-1 - partner]
        e = shapes.plane_restitution[-1 - partner]
    else:
        f = shapes.friction[partner]
        e = shapes.restitution[partner]
    return f, e


@ti.func
def collide_pairs_loops(c: ti.template(), bp: ti.template(), shapes: ti.template(), bodies: ti.template(),
                        pool: ti.template(), cache: ti.template(), margin: ti.f32, slop: ti.f32,
                        overlap_depth: ti.f32, h: ti.f32, speculative: ti.template(), reuse_d2: ti.f32,
                        reuse_sin: ti.f32, kinds: ti.template(), awake: ti.template(), dispatch: ti.template()):
    """Narrowphase over every candidate pair, then pack the points and manifolds.

    The pair's margin is the speculative distance (capped at a quarter of the smaller
    shape's bound, so millimetre bodies stay sane) plus how far the two can close in
    the step ``h``: points that may touch before the step ends are generated now and
    the solver closes the gap exactly (speculative contacts: no tunnelling). The
    slop is likewise capped at 2 % of the smaller bound (a millimetre cube tolerates 17 um). A pair
    of a body just placed (``bodies.placed``) deeper than its slop plus ``overlap_depth`` x that
    bound is marked overlapping (manifold_cache.carry_overlap). ``kinds`` (the shape
    kinds the scene contains, a static tuple) keeps routines for absent kinds out of
    the compiled kernel (house rule 8). A pair whose relative pose moved less than
    ``reuse_d2`` (squared distance) and whose relative rotation's half-angle sine stays
    below ``reuse_sin`` takes last step's manifold back (manifold_cache.py). ``awake``
    (awake.py): the shapes that enumerated the pairs (``pair_search.find_pairs_loops``); in a
    sleeping world a pair with points whose partner sleeps marks that island to wake."""
    n_pairs = ti.min(bp.pair_total[None], bp.pair_capacity)
    start_step(cache)
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for p in range(n_pairs):
        i = bp.pair_a[p]
        j = bp.pair_b[p]
        a = shape_pose(shapes, bodies, i)
        b = ShapePose()
        if j < 0:
            b = plane_pose(shapes, -1 - j)
        else:
            b = shape_pose(shapes, bodies, j)
        small = ti.min(a.bound, b.bound)
        swept = swept_distance(shapes, bodies, i, h, speculative)
        if j >= 0:
            swept += swept_distance(shapes, bodies, j, h, speculative)
        pair_margin = ti.min(margin, 0.25 * small) + swept
        pair_slop = ti.min(slop, SLOP_FRACTION * small)
        c.raw_slop[p] = pair_slop
        c.raw_size[p] = small
        m = Manifold(count=0, normal=vec3(0.0, 0.0, 1.0))
        found = old_slot(cache, i, j)
        o = find_reusable(cache, found, a, b, pair_margin, reuse_d2, reuse_sin)
        if o >= 0:
            m = reuse_manifold(cache, o, p, a, b)
        else:
            m = collide_kinds(pool, a, b, pair_margin, kinds)
            remember_manifold(cache, p, j, m, a, b)
        placed = bodies.placed[shapes.body[i]] | bodies.placed[partner_body(shapes, j)]
        carry_overlap(cache, p, found, placed, m, pair_slop + overlap_depth * small)
        if ti.static(awake.compact):  # a sleeping world: touching a sleeping body wakes its island
            if m.count > 0 and j >= 0:
                note_touch(awake, shapes.body[j])
        c.raw_count[p] = m.count
        c.has_points[p] = 1 if m.count > 0 else 0
        c.raw_normal[p] = m.normal
        for k in range(m.count):
            s = MAX_POINTS * p + k
            c.raw_point[s] = vec3(m.points[k, 0], m.points[k, 1], m.points[k, 2])
            c.raw_sep[s] = m.separation[k]
            c.raw_feature[s] = m.feature[k]
    exclusive_scan(c.scanner, c.raw_count, c.point_start, n_pairs, c.count)
    exclusive_scan(c.scanner, c.has_points, c.manifold_index, n_pairs, c.manifold_count)
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for p in range(n_pairs):
        cnt = c.raw_count[p]
        if cnt > 0:
            i = bp.pair_a[p]
            j = bp.pair_b[p]
            ba = shapes.body[i]
            bb = partner_body(shapes, j)
            fb, eb = partner_material(shapes, j)
            mu = ti.sqrt(shapes.friction[i] * fb)
            e = ti.max(shapes.restitution[i], eb)
            base = c.point_start[p]
            mi = c.manifold_index[p]
            c.m_body_a[mi] = ba
            c.m_body_b[mi] = bb
            c.m_start[mi] = base
            c.m_count[mi] = cnt
            for k in range(cnt):
                s = MAX_POINTS * p + k
                q = base + k
                c.body_a[q] = ba
                c.body_b[q] = bb
                c.shape_a[q] = i
                c.partner[q] = j
                c.feature[q] = c.raw_feature[s]
                c.manifold[q] = mi
                c.normal[q] = c.raw_normal[p]
                c.point[q] = c.raw_point[s]
                # the narrowphase saw float32 positions; the bodies sit pos_rem further on
                c.sep[q] = c.raw_sep[s] + dot(c.raw_normal[p], bodies.pos_rem[bb] - bodies.pos_rem[ba])
                c.friction[q] = mu
                c.restitution[q] = e
                c.slop[q] = c.raw_slop[p]
                c.size[q] = c.raw_size[p]
                c.overlap[q] = cache.overlap[cache.parity[None], p]  # carry_overlap's mark (close_step flips later)
    n_shapes = shape_total(shapes, awake)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n_shapes):
        i = shape_id(shapes, awake, k)
        p0 = bp.pair_start[k]
        p1 = bp.pair_start[k + 1]
        c.shape_first[i] = c.point_start[ti.min(p0, n_pairs)]
        c.shape_last[i] = c.point_start[ti.min(p1, n_pairs)]
    close_step(cache, bp, shapes, n_pairs, awake)


@ti.kernel
def collide_pairs(c: ti.template(), bp: ti.template(), shapes: ti.template(), bodies: ti.template(),
                  pool: ti.template(), cache: ti.template(), margin: ti.f32, slop: ti.f32, overlap_depth: ti.f32,
                  h: ti.f32, speculative: ti.template(), reuse_d2: ti.f32, reuse_sin: ti.f32, kinds: ti.template(),
                  awake: ti.template(), dispatch: ti.template()):
    collide_pairs_loops(c, bp, shapes, bodies, pool, cache, margin, slop, overlap_depth, h, speculative, reuse_d2,
                        reuse_sin, kinds, awake, dispatch)


@ti.func
def clear_contacts_loops(c: ti.template(), bp: ti.template()):
    """No contact and no pair yet: a world uploaded into a pooled buffer (build.upload) would
    otherwise show, until its first collision, the contacts its buffer's previous world left,
    with that world's body indices (``World.metrics()`` before the first step hung labelling
    islands over them)."""
    c.count[None] = 0
    c.manifold_count[None] = 0
    bp.pair_total[None] = 0
    bp.listed[None] = 0  # and every shape searches for its pairs

@ti.kernel
def clear_contacts(c: ti.template(), bp: ti.template()):
    clear_contacts_loops(c, bp)
