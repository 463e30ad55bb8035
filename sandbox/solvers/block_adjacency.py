"""The scratch a Jacobi-family sweep works in: every dynamic body's sorted block endpoints, its
split count n_b and the scale and weight its blocks see, built once a step.

What n_b counts, and why the scale and weight are what they are, is mass splitting's own story
(mass_splitting.py's docstring); this module builds them, with the light bodies whose blocks take
extra sweeps (light_bodies.py). Every schedule builds it: the support update walks the same
endpoints (mass_splitting.update_support), and PGS's warm start uses the merge.
"""

import taichi as ti

from ..backend import serialize_light_loops
from ..lanes import LANE_BITS, LANES, lane_capacity
from ..prefix_sum import Scanner, exclusive_scan, sort_range
from .contact_spring import BAUMGARTE_RATE, GRAVITY_REACH, IDLE_SHARE, RESTITUTION_THRESHOLD, SPLIT_BOUND, STEP_DT
from .light_bodies import list_light_block, list_light_body, mark_light, reset_light_lists

PER_POINT = 0
PER_MANIFOLD = 1
MODE_JACOBI = 0
MODE_SPLIT = 1
MODE_JACOBI_BOUNDED = 2


@ti.data_oriented
class BlockScratch:
    def __init__(self, block_capacity: int, body_capacity: int):
        bc = lane_capacity(max(16, block_capacity))
        nb = max(1, body_capacity)
        self.block_capacity = bc
        self.block_count = ti.field(ti.i32, ())
        self.adj_count = ti.field(ti.i32, nb + 1)
        self.adj_start = ti.field(ti.i32, nb + 1)
        self.adj_fill = ti.field(ti.i32, nb)
        self.adj_total = ti.field(ti.i32, ())
        self.adj = ti.field(ti.i32, 2 * bc)
        # a block's velocity changes (dv, dw) of its body a (side 0) and b (side 1), in groups of
        # eight blocks that the lane sweep stores a row at a time (lanes.py):
        # ``[side, group][0:3 dv / 3:6 dw, lane]``, read and written through ``slot_change`` and
        # ``store_slots``
        self.slots = ti.Matrix.field(6, LANES, ti.f32, (2, bc // LANES))
        self.active_count = ti.field(ti.i32, nb)  # blocks of the body that can act this step (n_b)
        self.fresh_count = ti.field(ti.i32, nb)  # of those, impacts (new and fast)
        self.scale = ti.field(ti.f32, nb)  # of the blocks counted in n_b
        self.weight = ti.field(ti.f32, nb)
        self.scale_idle = ti.field(ti.f32, nb)  # of the body's other blocks (idle_split)
        self.global_scale = ti.field(ti.f32, ())  # MODE_JACOBI_BOUNDED's one factor, this step
        self.body_capacity = nb
        # light bodies and their blocks' extra sweeps (light_bodies.py)
        self.light = ti.field(ti.i32, nb)  # 1: the body rests against one ratio_mass times heavier
        self.block_light = ti.field(ti.i32, bc)  # 1: one of the block's bodies is light
        self.light_blocks = ti.field(ti.i32, bc)  # the blocks of light bodies, in no set order
        self.light_block_count = ti.field(ti.i32, ())
        self.light_bodies = ti.field(ti.i32, nb)  # the bodies those blocks touch, in no set order
        self.light_body_count = ti.field(ti.i32, ())
        self.light_sweeps = ti.field(ti.i32, ())  # this step's extra sweeps of those blocks (0: none)
        self.scanner = Scanner(nb + 1)


@ti.func
def slot_change(s: ti.template(), slot: ti.i32):
    """(dv, dw) in adjacency slot ``slot`` (2 k + side: block k's change of its body a or b)."""
    side, k = slot & 1, slot >> 1  # slot >= 0: bit operations, not signed division
    g, l = k >> LANE_BITS, k & (LANES - 1)
    dv = ti.math.vec3(s.slots[side, g][0, l], s.slots[side, g][1, l], s.slots[side, g][2, l])
    dw = ti.math.vec3(s.slots[side, g][3, l], s.slots[side, g][4, l], s.slots[side, g][5, l])
    return dv, dw


@ti.func
def store_slots(s: ti.template(), k: ti.i32, dva, dwa, dvb, dwb):
    """Block k's changes of its bodies a and b into its two slots."""
    g, l = k >> LANE_BITS, k & (LANES - 1)
    for e in ti.static(range(3)):
        s.slots[0, g][e, l] = dva[e]
        s.slots[0, g][3 + e, l] = dwa[e]
        s.slots[1, g][e, l] = dvb[e]
        s.slots[1, g][3 + e, l] = dwb[e]


@ti.func
def block_range(c: ti.template(), k: ti.i32, kind: ti.template()):
    start, count, a, b = k, 1, 0, 0
    if ti.static(kind == PER_POINT):
        a = c.body_a[k]
        b = c.body_b[k]
    else:
        start = c.m_start[k]
        count = c.m_count[k]
        a = c.m_body_a[k]
        b = c.m_body_b[k]
    return start, count, a, b


@ti.func
def n_blocks(c: ti.template(), kind: ti.template()) -> ti.i32:
    n = 0
    if ti.static(kind == PER_POINT):
        n = c.count[None]
    else:
        n = c.manifold_count[None]
    return n


@ti.func
def _point_can_act(c: ti.template(), rows: ti.template(), q: ti.i32) -> ti.i32:
    """Point q touches or penetrates, carries a warm-start impulse, or closes its gap within
    the step at its approach speed (rows.prepare_row and the warm-start match ran before).
    Under the paper formulation every point counts, as in the paper: its rigid rows have no
    compliance to absorb a sub-body count that a point joining mid-solve makes too small."""
    sep = c.sep[q]
    closing = sep + ti.min(rows.approach[q], 0.0) * rows.params[STEP_DT] - rows.params[GRAVITY_REACH]
    return ti.cast(sep <= 0.0 or rows.lam[q][0] > 0.0 or closing <= 0.0 or rows.params[BAUMGARTE_RATE] > 0.0,
                   ti.i32)


@ti.func
def _block_can_act(c: ti.template(), rows: ti.template(), k: ti.i32, kind: ti.template()):
    """(whether block k can act, whether it is an impact: a new contact, without a warm-start
    impulse, approaching faster than the restitution threshold)."""
    start, count, _, _ = block_range(c, k, kind)
    act = 0
    warm = 0
    fast = 0
    for q in range(start, start + count):
        act |= _point_can_act(c, rows, q)
        warm |= ti.cast(rows.lam[q][0] > 0.0, ti.i32)
        fast |= ti.cast(rows.approach[q] < -rows.params[RESTITUTION_THRESHOLD], ti.i32)
    return act, act * (1 - warm) * fast


@ti.func
def build_adjacency_loops(s: ti.template(), c: ti.template(), bodies: ti.template(), rows: ti.template(),
                          kind: ti.template(), mode: ti.template(), omega: ti.f32):
    """Each dynamic body's sorted block endpoints, its split count and its scale and weight
    (module docstring; under ``MODE_JACOBI_BOUNDED`` every body takes ``global_scale``, the
    busiest body's split), and the light bodies (marked in the blocks that can act; under a fixed
    Jacobi relaxation, MODE_JACOBI, in every block), all of whose blocks take this step's extra
    sweeps (Settings.ratio_sweeps; ``light_sweeps`` is their count, 0 without a light body:
    light_bodies.py). Reads this step's rows and warm-start impulses (the split count)."""
    nb = bodies.count[None]
    nk = n_blocks(c, kind)
    s.block_count[None] = nk
    reset_light_lists(s)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        s.adj_count[i] = 0
        s.adj_fill[i] = 0
        s.active_count[i] = 0
        s.fresh_count[i] = 0
        s.light[i] = 0
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(nk):
        _, _, a, b = block_range(c, k, kind)
        act = 1
        fresh = 0
        if ti.static(mode != MODE_JACOBI):
            act, fresh = _block_can_act(c, rows, k, kind)
        if act:
            mark_light(s, rows, bodies, a, b)
        if ti.static(mode != MODE_SPLIT):
            act = 1  # one global factor: every block counted
        start, count, _, _ = block_range(c, k, kind)
        for q in range(start, start + count):
            rows.counted[q] = act
        if bodies.inv_mass[a] > 0.0:
            ti.atomic_add(s.adj_count[a], 1)
            ti.atomic_add(s.active_count[a], act)
            ti.atomic_add(s.fresh_count[a], fresh)
        if bodies.inv_mass[b] > 0.0:
            ti.atomic_add(s.adj_count[b], 1)
            ti.atomic_add(s.active_count[b], act)
            ti.atomic_add(s.fresh_count[b], fresh)
    exclusive_scan(s.scanner, s.adj_count, s.adj_start, nb, s.adj_total)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(nk):
        _, _, a, b = block_range(c, k, kind)
        list_light_block(s, k, a, b)
        if bodies.inv_mass[a] > 0.0:
            s.adj[s.adj_start[a] + ti.atomic_add(s.adj_fill[a], 1)] = 2 * k
        if bodies.inv_mass[b] > 0.0:
            s.adj[s.adj_start[b] + ti.atomic_add(s.adj_fill[b], 1)] = 2 * k + 1
    if ti.static(mode == MODE_JACOBI_BOUNDED):
        s.global_scale[None] = 1.0 / omega
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        sort_range(s.adj, s.adj_start[i], s.adj_start[i + 1])
        list_light_body(s, rows, i)
        if ti.static(mode == MODE_JACOBI_BOUNDED):  # max is exact in any order: the same bits
            relax = rows.params[SPLIT_BOUND] if s.fresh_count[i] == 0 else 1.0
            ti.atomic_max(s.global_scale[None], ti.cast(s.adj_count[i], ti.f32) / relax)
        if ti.static(mode == MODE_SPLIT):
            # over-relaxation makes up for the split's slack (n_b contacts rarely push one way),
            # so a body's scale never drops below one sub-body: a lone block stays exact
            # ... but not while an impact arrives: over-relaxing it overshoots
            # (a debris box landing at 9.6 m/s left at 20.8 m/s, docs/method-notes.md)
            relax = omega if s.fresh_count[i] == 0 else 1.0
            split = ti.max(ti.cast(ti.max(s.active_count[i], 1), ti.f32) / relax, 1.0)
            idle = s.adj_count[i] - s.active_count[i]
            s.scale_idle[i] = split
            if idle > 0:  # uncounted blocks that still act must not break B >= A (idle_split)
                share = rows.params[IDLE_SHARE]
                split = split / (1.0 - share)
                s.scale_idle[i] = ti.cast(idle, ti.f32) / share
            s.scale[i] = split
            s.weight[i] = 1.0 / split
        if ti.static(mode == MODE_JACOBI):
            s.scale[i] = 1.0 / omega
            s.weight[i] = omega
            s.scale_idle[i] = 1.0 / omega
    if ti.static(mode == MODE_JACOBI_BOUNDED):
        ti.loop_config(serialize=ti.static(serialize_light_loops()))
        for i in range(nb):
            s.scale[i] = s.global_scale[None]
            s.weight[i] = 1.0 / s.global_scale[None]
            s.scale_idle[i] = s.global_scale[None]


@ti.kernel
def build_adjacency(s: ti.template(), c: ti.template(), bodies: ti.template(), rows: ti.template(),
                    kind: ti.template(), mode: ti.template(), omega: ti.f32):
    build_adjacency_loops(s, c, bodies, rows, kind, mode, omega)
