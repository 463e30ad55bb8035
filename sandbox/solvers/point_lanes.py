"""The per-point blocks' sweep eight points at a time, on the CPU's vector units.

``mass-splitting`` and ``jacobi`` solve every contact point as a block of its own
(mass_splitting.py): the same few dozen multiply-adds on each point's rows, independent across
the points of a sweep. Written point by point (mass_splitting.sweep_block), LLVM runs them one
point at a time; written as one expression over eight consecutive points' values, it runs each
as one 8-wide instruction, provided the eight values come from one field element (lanes.py).
So the team (team_loop.iterate_shared) first copies the rows a sweep reads into ``LaneRows``, in
groups of eight points (once a step: they change only between steps; ``lane_copy_phase``, which in
the one-launch step also works out the responses it copies: rows.share_row, rows.respond_row), and every
sweep of per-point blocks then goes group by group (``lane_block_phase``), its slots stored in groups too
(block_adjacency.store_slots). A relax sweep's separations (two rotations a point) go eight at a
time as well; what differs from point to point in a biased sweep (the spring's push-out, a capped
row's manifold walk: normal_target; the fast-push test) is computed lane by lane through the
scalar code; the accumulated impulses stay in ``rows.lam``, read and written lane by lane, as
every other stage reads them.

Every arithmetic operation is the scalar path's, in its order, on the same floats (``fast_math``
is off, backend.py, so LLVM packs operations but never reorders them): the same bits as
sweep_block (tests/test_solvers.py compares the team's launch with the others; the state hashes
did not move). Rolling friction, the manifold blocks, the light bodies' extra sweeps and the
restitution pass keep the scalar path. Measured: docs/bench.md, "Twelfth pass" and "Nineteenth pass";
benchmarks/lane_sweep.py times this sweep against sweep_block.
"""

import taichi as ti

from ..lanes import LANES, lane_group_field
from ..pose_lanes import POSE_ROWS, lane_quat_rotate
from . import team as tm
from .block_adjacency import PER_POINT
from .contact_spring import INV_H, RELAX_PUSH
from .normal_target import BIASED, normal_target, pushes_fast
from .rows import ROLLING, SLIDING, respond_row, share_row
from .split_scales import block_weights

lanes = ti.types.vector(LANES, ti.f32)
vec3 = ti.math.vec3

LIN_A, LIN_B, SOFT_K, GAMMA, PRELOAD, FRICTION, WEIGHT_A, WEIGHT_B = range(8)
"""Rows of ``LaneRows.scalars``: s_a / m_a, s_b / m_b, 1 / (K~_n + gamma), gamma, the preload, the
friction coefficient and the merge weights of bodies a and b (split_scales.block_weights)."""
SCALARS = 8


@ti.data_oriented
class LaneRows:
    """The rows a per-point sweep reads, copied per step into groups of eight points (lanes.py):
    ``[group][row, lane]``. ``vectors``: normal, t1, t2 and the inverse effective masses, three
    rows each; ``ang_a`` ... ``resp_b``: rows.py's 3 x 3 matrices, row r * 3 + e; ``scalars``:
    the LIN_A ... WEIGHT_B rows; ``target``: the normal rows' targets of the sweep under way;
    ``poses``: the bodies' new poses in groups of eight, the position update's out-rows
    (pose_lanes.POSE_ROWS)."""

    def __init__(self, point_capacity: int, body_capacity: int):
        tree = ti.FieldsBuilder()  # ~710 field nodes: a tree of their own (lanes.lane_group_field)
        self.vectors = lane_group_field(12, point_capacity, builder=tree)
        self.ang_a = lane_group_field(9, point_capacity, builder=tree)
        self.ang_b = lane_group_field(9, point_capacity, builder=tree)
        self.resp_a = lane_group_field(9, point_capacity, builder=tree)
        self.resp_b = lane_group_field(9, point_capacity, builder=tree)
        self.scalars = lane_group_field(SCALARS, point_capacity, builder=tree)
        self.anchors = lane_group_field(ANCHORS, point_capacity, builder=tree)
        self.target = lane_group_field(1, point_capacity, builder=tree)
        self.poses = lane_group_field(POSE_ROWS, body_capacity, builder=tree)  # pose_lanes.py
        self.tree = tree.finalize()


NORMAL, T1, T2, INV_K = 0, 3, 6, 9
"""First rows of the four vectors in ``LaneRows.vectors``."""

RA, RB, RA_BODY, RB_BODY, SEP = 0, 3, 6, 9, 12
"""Rows of ``LaneRows.anchors``: the anchors r_a, r_b at the step start, the same in the bodies'
frames, and the separation at the step start: what a relax sweep's separation now is made of
(normal_target.current_separation)."""
ANCHORS = 13


def lanes_apply(kind: int, friction: int) -> bool:
    """Whether the biased and relax sweeps of ``kind`` blocks go eight points at a time."""
    return kind == PER_POINT and not (friction & ROLLING)


@ti.func
def copy_group(lr: ti.template(), s: ti.template(), rows: ti.template(), c: ti.template(), g: ti.i32, n: ti.i32):
    """Points 8 g .. 8 g + 7 of this step's rows into group g (a lane past the count ``n`` copies
    the last point: its results are never kept). The lanes are a run-time loop, not an unrolled
    one: a copy once a step needs no vector code, and eight unrolled copies of ~70 loads were a
    large part of the team kernel's compile time (docs/bench.md, "Thirteenth pass")."""
    vectors = ti.Matrix.zero(ti.f32, 12, LANES)
    scalars = ti.Matrix.zero(ti.f32, SCALARS, LANES)
    ang_a = ti.Matrix.zero(ti.f32, 9, LANES)
    ang_b = ti.Matrix.zero(ti.f32, 9, LANES)
    resp_a = ti.Matrix.zero(ti.f32, 9, LANES)
    resp_b = ti.Matrix.zero(ti.f32, 9, LANES)
    anchors = ti.Matrix.zero(ti.f32, ANCHORS, LANES)
    for l in range(LANES):
        q = ti.min(g * LANES + l, n - 1)
        for e in ti.static(range(3)):
            vectors[NORMAL + e, l] = c.normal[q][e]
            vectors[T1 + e, l] = rows.t1[q][e]
            vectors[T2 + e, l] = rows.t2[q][e]
            vectors[INV_K + e, l] = rows.inv_k[q][e]
            anchors[RA + e, l] = rows.ra[q][e]
            anchors[RB + e, l] = rows.rb[q][e]
            anchors[RA_BODY + e, l] = rows.ra_body[q][e]
            anchors[RB_BODY + e, l] = rows.rb_body[q][e]
            for r in ti.static(range(3)):
                ang_a[r * 3 + e, l] = rows.ang_a[q][r, e]
                ang_b[r * 3 + e, l] = rows.ang_b[q][r, e]
                resp_a[r * 3 + e, l] = rows.resp_a[q][r, e]
                resp_b[r * 3 + e, l] = rows.resp_b[q][r, e]
        wa, wb = block_weights(s, rows, q, c.body_a[q], c.body_b[q])
        scalars[LIN_A, l] = rows.lin_a[q]
        scalars[LIN_B, l] = rows.lin_b[q]
        scalars[SOFT_K, l] = rows.inv_k_soft[q]
        scalars[GAMMA, l] = rows.gamma[q]
        scalars[PRELOAD, l] = rows.preload[q]
        scalars[FRICTION, l] = c.friction[q]
        scalars[WEIGHT_A, l] = wa
        scalars[WEIGHT_B, l] = wb
        anchors[SEP, l] = c.sep[q]
    lr.vectors[g] = vectors
    lr.scalars[g] = scalars
    lr.ang_a[g] = ang_a
    lr.ang_b[g] = ang_b
    lr.resp_a[g] = resp_a
    lr.resp_b[g] = resp_b
    lr.anchors[g] = anchors


@ti.func
def _row(m, r: ti.template()) -> lanes:
    v = lanes(0.0)
    for l in ti.static(range(LANES)):
        v[l] = m[r, l]
    return v


@ti.func
def _dot(x0, x1, x2, y0, y1, y2):
    """math3d.dot, component by component: the products summed left to right."""
    return x0 * y0 + x1 * y1 + x2 * y2


@ti.func
def _biased_targets(lr: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), g: ti.i32,
                    n: ti.i32) -> ti.i32:
    """The group's biased normal targets, point by point (normal_target: the spring's push-out,
    a capped row's manifold walk) into ``lr.target``; returns whether a row pushes fast."""
    fast = 0
    for l in range(ti.min(LANES, n - g * LANES)):
        q = g * LANES + l
        target, _ = normal_target(rows, c, bodies, q, BIASED)
        if rows.params[RELAX_PUSH] > 0.0:
            fast = ti.max(fast, pushes_fast(rows, c, q))
        lr.target[g][0, l] = target
    return fast


@ti.func
def _relax_targets(lr: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), nrm, g: ti.i32,
                   n: ti.i32) -> lanes:
    """The group's relax normal targets on eight lanes: each point's separation now
    (normal_target.current_separation, its operations in its order; kept in ``rows.sep_now`` for
    the next biased sweep), a gap's s / h, else 0. Point by point, the two rotations were half of a
    relax sweep's time (docs/bench.md, "Nineteenth pass")."""
    anchors = lr.anchors[g]
    moved_a = [lanes(0.0), lanes(0.0), lanes(0.0)]
    moved_b = [lanes(0.0), lanes(0.0), lanes(0.0)]
    rot_a = [lanes(0.0), lanes(0.0), lanes(0.0), lanes(0.0)]
    rot_b = [lanes(0.0), lanes(0.0), lanes(0.0), lanes(0.0)]
    for l in ti.static(range(LANES)):
        q = ti.min(g * LANES + l, n - 1)  # a lane past the count works on the last point, unkept
        a = c.body_a[q]
        b = c.body_b[q]
        for e in ti.static(range(3)):
            moved_a[e][l] = bodies.moved[a][e]
            moved_b[e][l] = bodies.moved[b][e]
        for e in ti.static(range(4)):
            rot_a[e][l] = bodies.rot[a][e]
            rot_b[e][l] = bodies.rot[b][e]
    body_a = [_row(anchors, RA_BODY + e) for e in ti.static(range(3))]
    body_b = [_row(anchors, RB_BODY + e) for e in ti.static(range(3))]
    turned_a = lane_quat_rotate(rot_a, body_a)
    turned_b = lane_quat_rotate(rot_b, body_b)
    da = [moved_a[e] + turned_a[e] - _row(anchors, RA + e) for e in ti.static(range(3))]
    db = [moved_b[e] + turned_b[e] - _row(anchors, RB + e) for e in ti.static(range(3))]
    sep = _row(anchors, SEP) + _dot(nrm[0], nrm[1], nrm[2], db[0] - da[0], db[1] - da[1], db[2] - da[2])
    for l in range(ti.min(LANES, n - g * LANES)):
        rows.sep_now[g * LANES + l] = sep[l]
    return ti.select(sep > 0.0, sep * rows.params[INV_H], 0.0)


@ti.func
def sweep_point_lanes(lr: ti.template(), s: ti.template(), rows: ti.template(), c: ti.template(),
                      bodies: ti.template(), biased: ti.i32, friction: ti.template(), then_warm: ti.i32,
                      g: ti.i32, n: ti.i32) -> ti.i32:
    """mass_splitting.sweep_block of the per-point blocks 8 g .. 8 g + 7 below ``n`` in a biased
    (``biased`` = 1) or relax sweep (rows.solve_point, the carried warm start when ``then_warm``,
    the weighted slots). Returns 1 when a biased row of them pushes fast, else 0. The kind of
    sweep is read at run time, so that the team's loop holds one copy of this code (its compile
    time: docs/bench.md, "Twelfth pass"): the biased row's preload is a lane-wise choice."""
    va = [lanes(0.0), lanes(0.0), lanes(0.0)]
    wa = [lanes(0.0), lanes(0.0), lanes(0.0)]
    vb = [lanes(0.0), lanes(0.0), lanes(0.0)]
    wb = [lanes(0.0), lanes(0.0), lanes(0.0)]
    lam = [lanes(0.0), lanes(0.0), lanes(0.0)]
    for l in ti.static(range(LANES)):
        q = ti.min(g * LANES + l, n - 1)  # a lane past the count works on the last point, unkept
        a = c.body_a[q]
        b = c.body_b[q]
        lam_q = rows.lam[q]
        for e in ti.static(range(3)):
            va[e][l] = bodies.lin_vel[a][e]
            wa[e][l] = bodies.ang_vel[a][e]
            vb[e][l] = bodies.lin_vel[b][e]
            wb[e][l] = bodies.ang_vel[b][e]
            lam[e][l] = lam_q[e]
    va0, wa0, vb0, wb0 = [x for x in va], [x for x in wa], [x for x in vb], [x for x in wb]
    vectors = lr.vectors[g]
    scalars = lr.scalars[g]
    ang_a = lr.ang_a[g]
    ang_b = lr.ang_b[g]
    resp_a = lr.resp_a[g]
    resp_b = lr.resp_b[g]
    ma = _row(scalars, LIN_A)
    mb = _row(scalars, LIN_B)
    nrm = [_row(vectors, NORMAL + e) for e in ti.static(range(3))]
    t1 = [_row(vectors, T1 + e) for e in ti.static(range(3))]
    t2 = [_row(vectors, T2 + e) for e in ti.static(range(3))]
    inv_k = [_row(vectors, INV_K + e) for e in ti.static(range(3))]
    if ti.static(friction & SLIDING):
        dl = [vb[e] - va[e] for e in ti.static(range(3))]
        f = [lanes(0.0), lanes(0.0)]
        tangents = [t1, t2]
        for r in ti.static(range(2)):
            t = tangents[r]
            jb = [_row(ang_b, (r + 1) * 3 + e) for e in ti.static(range(3))]
            ja = [_row(ang_a, (r + 1) * 3 + e) for e in ti.static(range(3))]
            f[r] = lam[r + 1] - (_dot(dl[0], dl[1], dl[2], t[0], t[1], t[2])
                                 + _dot(wb[0], wb[1], wb[2], jb[0], jb[1], jb[2])
                                 - _dot(wa[0], wa[1], wa[2], ja[0], ja[1], ja[2])) * inv_k[r + 1]
        limit = _row(scalars, FRICTION) * lam[0]
        mag = ti.sqrt(f[0] * f[0] + f[1] * f[1])
        over = mag > limit
        scale = limit / mag
        f1 = ti.select(over, f[0] * scale, f[0])
        f2 = ti.select(over, f[1] * scale, f[1])
        d1 = f1 - lam[1]
        d2 = f2 - lam[2]
        for e in ti.static(range(3)):
            imp = t1[e] * d1 + t2[e] * d2
            va[e] = va[e] - ma * imp
            wa[e] = wa[e] - (_row(resp_a, 3 + e) * d1 + _row(resp_a, 6 + e) * d2)
            vb[e] = vb[e] + mb * imp
            wb[e] = wb[e] + (_row(resp_b, 3 + e) * d1 + _row(resp_b, 6 + e) * d2)
        lam[1] = f1
        lam[2] = f2
    # the normal row
    fast = 0
    target = lanes(0.0)
    if biased:
        fast = _biased_targets(lr, rows, c, bodies, g, n)
        target = _row(lr.target[g], 0)
    else:
        target = _relax_targets(lr, rows, c, bodies, nrm, g, n)
    ja0 = [_row(ang_a, e) for e in ti.static(range(3))]
    jb0 = [_row(ang_b, e) for e in ti.static(range(3))]
    vn = (_dot(vb[0] - va[0], vb[1] - va[1], vb[2] - va[2], nrm[0], nrm[1], nrm[2])
          + _dot(wb[0], wb[1], wb[2], jb0[0], jb0[1], jb0[2]) - _dot(wa[0], wa[1], wa[2], ja0[0], ja0[1], ja0[2]))
    ln = lam[0] - (vn + target) * inv_k[0]
    pre = _row(scalars, PRELOAD)  # a biased row: compliance on the impulse beyond the preload only
    soft = lam[0] - (vn + target + _row(scalars, GAMMA) * (lam[0] - pre)) * _row(scalars, SOFT_K)
    ln = ti.select(ti.Vector([biased] * LANES, ti.i32) != 0, ti.select(ln > pre, soft, ln), ln)
    ln = ti.max(ln, 0.0)
    d = ln - lam[0]
    for e in ti.static(range(3)):
        va[e] = va[e] - ma * d * nrm[e]
        wa[e] = wa[e] - _row(resp_a, e) * d
        vb[e] = vb[e] + mb * d * nrm[e]
        wb[e] = wb[e] + _row(resp_b, e) * d
    lam[0] = ln
    for l in range(ti.min(LANES, n - g * LANES)):
        rows.lam[g * LANES + l] = vec3(lam[0][l], lam[1][l], lam[2][l])
    # the next substep's warm start on the copies when ``then_warm`` (mass_splitting._apply_accumulated),
    # chosen lane-wise rather than branched on: the copies stay values, not variables
    warm = ti.Vector([then_warm] * LANES, ti.i32) != 0
    for e in ti.static(range(3)):
        imp = nrm[e] * lam[0] + t1[e] * lam[1] + t2[e] * lam[2]
        dwa = lanes(0.0)
        dwb = lanes(0.0)
        for r in ti.static(range(3)):
            dwa += _row(resp_a, r * 3 + e) * lam[r]
            dwb += _row(resp_b, r * 3 + e) * lam[r]
        va[e] = ti.select(warm, va[e] - ma * imp, va[e])
        wa[e] = ti.select(warm, wa[e] - dwa, wa[e])
        vb[e] = ti.select(warm, vb[e] + mb * imp, vb[e])
        wb[e] = ti.select(warm, wb[e] + dwb, wb[e])
    weight_a = _row(scalars, WEIGHT_A)
    weight_b = _row(scalars, WEIGHT_B)
    s.slots[0, g] = ti.Matrix.rows([(va[e] - va0[e]) * weight_a for e in ti.static(range(3))]
                                   + [(wa[e] - wa0[e]) * weight_a for e in ti.static(range(3))])
    s.slots[1, g] = ti.Matrix.rows([(vb[e] - vb0[e]) * weight_b for e in ti.static(range(3))]
                                   + [(wb[e] - wb0[e]) * weight_b for e in ti.static(range(3))])
    return fast


@ti.func
def lane_block_phase(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, lr: ti.template(),
                     s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                     friction: ti.template(), biased: ti.i32, then_warm: ti.i32, fast_slot: ti.i32) -> ti.i32:
    """Phase p: one biased or relax sweep of the per-point blocks, eight at a time, its items
    the groups of ``lr``. Returns the next phase (solvers/team.py)."""
    n = s.block_count[None]
    items = (n + LANES - 1) // LANES
    lo, hi, j = tm.next_chunk(team, p, items, member, members, 0)
    while lo < hi:
        for g in range(lo, hi):
            if sweep_point_lanes(lr, s, rows, c, bodies, biased, friction, then_warm, g, n):
                team.fast[fast_slot] = 1
        tm.finish(team, p, hi - lo)
        lo, hi, j = tm.next_chunk(team, p, items, member, members, j)
    tm.wait(team, p, items)
    return p + 1


@ti.func
def lane_copy_phase(team: ti.template(), p: ti.i32, member: ti.i32, members: ti.i32, lr: ti.template(),
                    s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                    responds: ti.template(), split: ti.template(), friction: ti.template()) -> ti.i32:
    """Phase p of the team's loop (solvers/team.py): this step's rows into ``lr``'s groups; with
    ``responds``, each group's points' response shares and responses first (rows.share_row,
    rows.respond_row, ``split`` its switch: the step's set-up left them to the team, whose threads
    share them and copy them while they are in cache)."""
    n = s.block_count[None]
    items = (n + LANES - 1) // LANES
    lo, hi, j = tm.next_chunk(team, p, items, member, members, 0)
    while lo < hi:
        for g in range(lo, hi):
            if ti.static(responds):
                for l in range(ti.min(LANES, n - g * LANES)):
                    share_row(rows, c, bodies, g * LANES + l)
                    respond_row(rows, c, bodies, s, split, friction, g * LANES + l)
            copy_group(lr, s, rows, c, g, n)
        tm.finish(team, p, hi - lo)
        lo, hi, j = tm.next_chunk(team, p, items, member, members, j)
    tm.wait(team, p, items)
    return p + 1
