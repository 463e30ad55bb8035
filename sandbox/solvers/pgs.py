"""Projected Gauss-Seidel, serial and graph-coloured, visiting manifolds as blocks.

``pgs`` is the deterministic serial reference: one serialized Taichi loop over
manifolds in buffer order (which is the deterministic pair order), every point
updating the real body velocities at once (method.md 1.2).

``pgs-colored`` is parallel PGS as GPUs run it: manifolds are greedily
coloured every step so no two manifolds of one colour share a dynamic body
(static bodies never conflict), colours run in sequence and each colour in
parallel (Box2D v3 ``constraint_graph.c``; one launch per colour per iteration).
With ``shuffle`` the manifolds and the colours are permuted by a seeded hash
every step, which reproduces the changing order of parallel hardware and the
jitter it causes. Manifolds that find no free colour among 64 go to an
overflow colour solved serially (as Box2D does).
"""


import numpy as np
import taichi as ti

from .visit_order import gauss_seidel_block

MAX_COLORS = 64


@ti.func
def solve_manifold(rows: ti.template(), c: ti.template(), bodies: ti.template(), m: ti.i32, mode: ti.template(),
                   friction: ti.template(), substep: ti.i32):
    """Manifold m's points one after another on its bodies' velocities, starting where the
    ``substep``-th substep of the step starts, an impact's until they settle
    (visit_order.gauss_seidel_block)."""
    a = c.m_body_a[m]
    b = c.m_body_b[m]
    va, wa = bodies.lin_vel[a], bodies.ang_vel[a]
    vb, wb = bodies.lin_vel[b], bodies.ang_vel[b]
    start, count = c.m_start[m], c.m_count[m]
    va, wa, vb, wb = gauss_seidel_block(rows, c, bodies, start, count, substep, va, wa, vb, wb, mode, friction)
    if bodies.inv_mass[a] > 0.0:
        bodies.lin_vel[a] = va
        bodies.ang_vel[a] = wa
    if bodies.inv_mass[b] > 0.0:
        bodies.lin_vel[b] = vb
        bodies.ang_vel[b] = wb


@ti.func
def pgs_sweep(rows: ti.template(), c: ti.template(), bodies: ti.template(), mode: ti.template(),
              friction: ti.template(), substep: ti.i32):
    """One serial sweep over the manifolds in buffer order (serialized also at a kernel's top level)."""
    ti.loop_config(serialize=True)
    for m in range(c.manifold_count[None]):
        solve_manifold(rows, c, bodies, m, mode, friction, substep)


@ti.kernel
def pgs_serial(rows: ti.template(), c: ti.template(), bodies: ti.template(), mode: ti.template(),
               friction: ti.template(), substep: ti.i32):
    """``pgs_sweep`` as its own launch (the stage-by-stage path)."""
    pgs_sweep(rows, c, bodies, mode, friction, substep)


@ti.data_oriented
class Coloring:
    def __init__(self, manifold_capacity: int, body_capacity: int):
        mc = max(16, manifold_capacity)
        self.order = ti.field(ti.i32, mc)
        self.color = ti.field(ti.i32, mc)
        self.sorted = ti.field(ti.i32, mc)
        self.mask = ti.field(ti.i64, max(1, body_capacity))
        self.color_start = ti.field(ti.i32, MAX_COLORS + 2)
        self.color_perm = ti.field(ti.i32, MAX_COLORS + 1)
        self.color_count = ti.field(ti.i32, ())
        self.cursor = ti.field(ti.i32, MAX_COLORS + 2)


@ti.func
def _hash(seed: ti.u32) -> ti.u32:
    # lowbias32 (Chris Wellons): a stateless, seedable, thread-order-free random stream
    x = seed
    x ^= x >> 16
    x *= ti.u32(0x7FEB352D)
    x ^= x >> 15
    x *= ti.u32(0x846CA68B)
    x ^= x >> 16
    return x


@ti.kernel
def color_manifolds(col: ti.template(), c: ti.template(), bodies: ti.template(), shuffle: ti.i32, seed: ti.i32,
                    step: ti.i32):
    ti.loop_config(serialize=True)
    for _ in range(1):
        nm = c.manifold_count[None]
        for idx in range(nm):
            col.order[idx] = idx
        key = _hash(ti.u32(seed) * ti.u32(0x9E3779B9) ^ _hash(ti.u32(step)))
        if shuffle:
            for t in range(nm - 1):
                u = nm - 1 - t
                key = _hash(key + ti.u32(u))
                w = ti.cast(key % ti.u32(u + 1), ti.i32)
                swap = col.order[u]
                col.order[u] = col.order[w]
                col.order[w] = swap
        for i in range(bodies.count[None]):
            col.mask[i] = ti.i64(0)
        for kc in range(MAX_COLORS + 2):
            col.color_start[kc] = 0
        used_colors = 0
        for idx in range(nm):
            m = col.order[idx]
            a = c.m_body_a[m]
            b = c.m_body_b[m]
            dyn_a = bodies.inv_mass[a] > 0.0
            dyn_b = bodies.inv_mass[b] > 0.0
            taken = ti.i64(0)
            if dyn_a:
                taken |= col.mask[a]
            if dyn_b:
                taken |= col.mask[b]
            first_free = 0
            while first_free < MAX_COLORS and (taken >> ti.i64(first_free)) & ti.i64(1) != 0:
                first_free += 1
            if first_free < MAX_COLORS:
                bit = ti.i64(1) << ti.i64(first_free)
                if dyn_a:
                    col.mask[a] |= bit
                if dyn_b:
                    col.mask[b] |= bit
                used_colors = ti.max(used_colors, first_free + 1)
            col.color[m] = first_free  # MAX_COLORS means overflow
        for k in range(MAX_COLORS + 1):
            col.color_perm[k] = k
        if shuffle:
            for t in range(used_colors - 1):
                u = used_colors - 1 - t
                key = _hash(key + ti.u32(u) * ti.u32(7919))
                w = ti.cast(key % ti.u32(u + 1), ti.i32)
                swap = col.color_perm[u]
                col.color_perm[u] = col.color_perm[w]
                col.color_perm[w] = swap
        for idx in range(nm):
            m = col.order[idx]
            col.color_start[col.color_perm[col.color[m]] + 1] += 1
        for k in range(MAX_COLORS + 1):
            col.color_start[k + 1] += col.color_start[k]
        for k in range(MAX_COLORS + 2):
            col.cursor[k] = col.color_start[k]
        for idx in range(nm):
            m = col.order[idx]
            slot = col.color_perm[col.color[m]]
            col.sorted[col.cursor[slot]] = m
            col.cursor[slot] += 1
        col.color_count[None] = used_colors


@ti.kernel
def solve_color(rows: ti.template(), c: ti.template(), bodies: ti.template(), col: ti.template(), k0: ti.i32,
                k1: ti.i32, mode: ti.template(), friction: ti.template(), substep: ti.i32):
    for idx in range(k0, k1):
        solve_manifold(rows, c, bodies, col.sorted[idx], mode, friction, substep)


@ti.kernel
def solve_overflow(rows: ti.template(), c: ti.template(), bodies: ti.template(), col: ti.template(), k0: ti.i32,
                   k1: ti.i32, mode: ti.template(), friction: ti.template(), substep: ti.i32):
    ti.loop_config(serialize=True)
    for idx in range(k0, k1):
        solve_manifold(rows, c, bodies, col.sorted[idx], mode, friction, substep)


@ti.func
def colored_sweep_in_order(rows: ti.template(), c: ti.template(), bodies: ti.template(), col: ti.template(),
                           mode: ti.template(), friction: ti.template(), substep: ti.i32):
    """The colours in sequence and each colour's manifolds one after another, for use inside a
    serialized loop (solvers/substep.py). No two manifolds of a colour share a dynamic body, so
    this gives bit for bit what the parallel launches per colour give."""
    for k in range(col.color_count[None]):
        for idx in range(col.color_start[k], col.color_start[k + 1]):
            solve_manifold(rows, c, bodies, col.sorted[idx], mode, friction, substep)
    for idx in range(col.color_start[MAX_COLORS], col.color_start[MAX_COLORS + 1]):
        solve_manifold(rows, c, bodies, col.sorted[idx], mode, friction, substep)


def color_ranges(col: Coloring) -> np.ndarray:
    return col.color_start.to_numpy()
