"""Islands: the groups of dynamic bodies joined by this step's contacts, labelled in kernels.

An island is a connected component of the graph whose nodes are the dynamic bodies and
whose edges are this step's manifolds between two dynamic bodies. A manifold is a touching
pair: it has at least one point, a speculative one within the margin included (Box2D's
``touching``). Static bodies join no island, so a pile on the ground is as many islands as
it has separate heaps, and one heap can sleep while its neighbour moves (sleep.py).

Each body's *label* is the smallest body index of its island, found by hooking and pointer
jumping (Shiloach and Vishkin's scheme): every body starts as its own label; a hook pass
over the edges lowers the label of the larger of the two roots to the smaller one (atomic
min), a jump pass points every body straight at its root; the passes repeat until no edge
joins two labels (a verify pass counts those). Labels only ever decrease and the fixed point
is unique (the component's minimum), so the labels are the same whatever the thread timing
and the edge order: deterministic on every backend. On the CPU the passes run serialized on
one thread (``serialize_light_loops``: a few microseconds each, cheaper than a thread-pool
dispatch), which also makes one round enough for most piles. The islands are then
numbered by an exclusive prefix sum over the roots (label == own index) in body order.

The loops take ``awake`` (awake.py): every body, or a sleeping world's awake ones. A
sleeping body keeps the label of the island it fell asleep with (sleep.py reads it to wake
the whole island at once). ``active`` (1 or 0) multiplies every loop's extent: a world that
keeps its awake lists with sleeping switched off labels nothing, in the same kernels.
"""

import taichi as ti

from .awake import body_id, body_total
from .backend import serialize_light_loops
from .prefix_sum import Scanner, exclusive_scan

ROUNDS = 4
"""Hook-and-jump rounds per launch; ``label_islands`` launches again until they converge."""


@ti.data_oriented
class Islands:
    def __init__(self, body_capacity: int):
        nb = max(1, body_capacity)
        self.label = ti.field(ti.i32, nb)  # smallest body index of the island; -1: static
        self.number = ti.field(ti.i32, nb)  # the island's number, 0.. in the order of the labels
        self.is_root = ti.field(ti.i32, nb + 1)  # per visited position: the body is its island's label
        self.root_rank = ti.field(ti.i32, nb + 1)
        self.count = ti.field(ti.i32, ())  # islands among the visited bodies
        self.split = ti.field(ti.i32, ())  # edges still joining two labels after the last round (0: done)
        self.scanner = Scanner(nb + 1)


@ti.func
def _edge(c: ti.template(), bodies: ti.template(), m: ti.i32):
    a = c.m_body_a[m]
    b = c.m_body_b[m]
    return a, b, bodies.inv_mass[a] > 0.0 and bodies.inv_mass[b] > 0.0


@ti.func
def start_labels(isl: ti.template(), bodies: ti.template(), awake: ti.template(), active: ti.i32):
    n = body_total(bodies, awake) * active
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(awake, k)
        isl.label[i] = i if bodies.inv_mass[i] > 0.0 else -1


@ti.func
def _hook(isl: ti.template(), c: ti.template(), bodies: ti.template(), active: ti.i32):
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for m in range(c.manifold_count[None] * active):
        a, b, joins = _edge(c, bodies, m)
        if joins:
            la = isl.label[a]
            lb = isl.label[b]
            if la < lb:
                ti.atomic_min(isl.label[lb], la)
            elif lb < la:
                ti.atomic_min(isl.label[la], lb)


@ti.func
def _jump(isl: ti.template(), bodies: ti.template(), awake: ti.template(), active: ti.i32):
    """Every body points at its root (roots do not change during this pass)."""
    n = body_total(bodies, awake) * active
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(awake, k)
        r = isl.label[i]
        if r >= 0:
            while isl.label[r] != r:
                r = isl.label[r]
            isl.label[i] = r


@ti.func
def _verify(isl: ti.template(), c: ti.template(), bodies: ti.template(), active: ti.i32):
    isl.split[None] = 0
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for m in range(c.manifold_count[None] * active):
        a, b, joins = _edge(c, bodies, m)
        if joins and isl.label[a] != isl.label[b]:
            ti.atomic_add(isl.split[None], 1)


@ti.func
def _number(isl: ti.template(), bodies: ti.template(), awake: ti.template(), active: ti.i32):
    """Consecutive numbers for the roots in body order (a prefix sum), then for every body its
    root's; ``count`` = the number of islands."""
    n = body_total(bodies, awake) * active
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(awake, k)
        isl.is_root[k] = 1 if isl.label[i] == i else 0
    exclusive_scan(isl.scanner, isl.is_root, isl.root_rank, n, isl.count)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(awake, k)
        if isl.is_root[k]:
            isl.number[i] = isl.root_rank[k]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(awake, k)
        r = isl.label[i]
        if r >= 0 and r != i:
            isl.number[i] = isl.number[r]
        elif r < 0:
            isl.number[i] = -1


@ti.func
def label_rounds(isl: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(), active: ti.i32):
    """ROUNDS hook-and-jump rounds, then the verify pass (``split`` = 0: converged) and the
    numbering (valid once converged). Top-level loops only: call it at a kernel's top level."""
    for _ in ti.static(range(ROUNDS)):
        _hook(isl, c, bodies, active)
        _jump(isl, bodies, awake, active)
    _verify(isl, c, bodies, active)
    _number(isl, bodies, awake, active)


@ti.kernel
def _label_kernel(isl: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                  first: ti.template()):
    if ti.static(first):
        start_labels(isl, bodies, awake, 1)
    label_rounds(isl, c, bodies, awake, 1)


def finish_labels(isl: Islands, c, bodies, awake) -> int:
    """More rounds until no edge joins two labels (rarely needed on the CPU); returns the count."""
    while int(isl.split[None]) > 0:
        _label_kernel(isl, c, bodies, awake, False)
    return int(isl.count[None])


def label_islands(isl: Islands, c, bodies, awake) -> int:
    """Label the islands of ``awake``'s bodies under the manifolds of ``c`` (contacts.Contacts,
    or anything with ``m_body_a``, ``m_body_b`` and ``manifold_count``); returns how many."""
    _label_kernel(isl, c, bodies, awake, True)
    return finish_labels(isl, c, bodies, awake)
