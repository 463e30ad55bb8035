"""What a sleeping island keeps: its contacts' warm-start impulses and its manifolds, per shape.

Every step rewrites the contact history (persistence.py) and the manifold cache
(manifold_cache.py) from the pairs it found, and a sleeping shape finds none: so when an
island falls asleep its shapes' records are copied here, and when it wakes they go back,
appended after the used part of the history and of the cache half that the next
narrowphase reads, with the shape's ranges pointing at them. The woken pairs then take
their manifolds back (the bodies have not moved: the cache's reuse test passes) and their
contacts last step's impulses, so a woken island starts exactly where it stopped (Box2D
keeps a sleeping island's contacts, manifolds and impulses in its solver set the same way).

Layout: per dynamic shape one range of history records (points) and one of manifold
records (pairs, each with MAX_POINTS point slots), in two halves. When islands fall asleep
the store is rebuilt into the other half from the still-sleeping shapes' ranges and the new
sleepers' live records, placed by prefix sums in shape order (deterministic), so the
ranges of woken shapes are dropped without a free list. A shape whose records would not
fit keeps none (it wakes without warm start; ``dropped`` counts them). The store is written
only when something falls asleep and read only when something wakes.
"""

import numpy as np
import taichi as ti

from .backend import serialize_light_loops
from .narrowphase.manifold import MAX_POINTS
from .persistence import HISTORY_FIELDS, owned_rows
from .prefix_sum import Scanner, exclusive_scan

FALLING, WAKING = 1, 2
"""A body's ``change`` in the sleep event under way (sleep.py): it falls asleep, or wakes."""

POINT_FIELDS = HISTORY_FIELDS
"""A history record (persistence.ContactHistory), per contact point."""
PAIR_FIELDS = ("partner", "count", "gap", "rel_pos", "rel_rot", "normal", "normal_on_b", "overlap")
SLOT_FIELDS = ("on_a", "on_b", "feature")
"""A manifold record (manifold_cache.ManifoldCache), per pair, and its per-point slots (MAX_POINTS
per manifold): ``ManifoldCache.<name>``, stored as ``m_<name>``."""


@ti.data_oriented
class SleepStore:
    def __init__(self, point_capacity: int, pair_capacity: int, shape_capacity: int):
        pc, mc, ns = max(16, point_capacity), max(16, pair_capacity), max(1, shape_capacity)
        self.point_capacity, self.pair_capacity = pc, mc
        self.parity = ti.field(ti.i32, ())  # the half that holds the sleeping shapes' records
        self.dropped = ti.field(ti.i32, ())  # shapes whose records did not fit, since the world began
        self.point_first = ti.field(ti.i32, (2, ns))
        self.point_last = ti.field(ti.i32, (2, ns))
        self.pair_first = ti.field(ti.i32, (2, ns))
        self.pair_last = ti.field(ti.i32, (2, ns))
        # history records
        self.partner = ti.field(ti.i32, (2, pc))
        self.feature = ti.field(ti.i32, (2, pc))
        self.anchor = ti.Vector.field(3, ti.f32, (2, pc))
        self.lam_n = ti.field(ti.f32, (2, pc))
        self.lam_t = ti.Vector.field(3, ti.f32, (2, pc))
        # manifold records
        self.m_partner = ti.field(ti.i32, (2, mc))
        self.m_count = ti.field(ti.i32, (2, mc))
        self.m_gap = ti.field(ti.f32, (2, mc))
        self.m_rel_pos = ti.Vector.field(3, ti.f32, (2, mc))
        self.m_rel_rot = ti.Vector.field(4, ti.f32, (2, mc))
        self.m_normal = ti.Vector.field(3, ti.f32, (2, mc))
        self.m_normal_on_b = ti.field(ti.i32, (2, mc))
        self.m_overlap = ti.field(ti.i32, (2, mc))
        self.m_on_a = ti.Vector.field(3, ti.f32, (2, mc * MAX_POINTS))
        self.m_on_b = ti.Vector.field(3, ti.f32, (2, mc * MAX_POINTS))
        self.m_feature = ti.field(ti.i32, (2, mc * MAX_POINTS))
        # scratch of a rebuild or a restore, per dynamic slot
        self.point_size = ti.field(ti.i32, ns + 1)
        self.pair_size = ti.field(ti.i32, ns + 1)
        self.point_at = ti.field(ti.i32, ns + 1)
        self.pair_at = ti.field(ti.i32, ns + 1)
        self.point_total = ti.field(ti.i32, ())
        self.pair_total = ti.field(ti.i32, ())
        self.pair_end = ti.field(ti.i32, ())  # restore: where the cache half's used part ends
        self.scanner = Scanner(ns + 1)

    # ------------------------------------------------------------------ host copies (rebuilds)
    def read(self) -> dict:
        """The current half's records as numpy arrays, with the owner shape of each record:
        what a rebuild of the world carries over (``sleep_rebuild.snapshot``)."""
        h = int(self.parity[None])
        pf, pl = self.point_first.to_numpy()[h], self.point_last.to_numpy()[h]
        mf, ml = self.pair_first.to_numpy()[h], self.pair_last.to_numpy()[h]
        point_rows = owned_rows(pf, pl)
        pair_rows = owned_rows(mf, ml)
        out = {"point_owner": point_rows[1], "pair_owner": pair_rows[1]}
        for name in POINT_FIELDS:
            out["point_" + name] = getattr(self, name).to_numpy()[h][point_rows[0]]
        for name in PAIR_FIELDS:
            out["pair_" + name] = getattr(self, "m_" + name).to_numpy()[h][pair_rows[0]]
        slots = (pair_rows[0][:, None] * MAX_POINTS + np.arange(MAX_POINTS)).reshape(-1)
        for name in SLOT_FIELDS:
            values = getattr(self, "m_" + name).to_numpy()[h][slots]
            out["slot_" + name] = values.reshape((len(pair_rows[0]), MAX_POINTS) + values.shape[1:])
        return out

    def write(self, records: dict) -> None:
        """Install ``read``'s records (owners sorted ascending, ids already remapped) in half 0."""
        point_owner, pair_owner = records["point_owner"], records["pair_owner"]
        points, pairs = len(point_owner), len(pair_owner)
        if points > self.point_capacity or pairs > self.pair_capacity:  # a smaller world than before: drop all
            points = pairs = 0
            point_owner, pair_owner = point_owner[:0], pair_owner[:0]
        shape_cap = self.point_first.shape[1]
        owners = np.arange(shape_cap)
        for first, last, owner in ((self.point_first, self.point_last, point_owner),
                                   (self.pair_first, self.pair_last, pair_owner)):
            lo = np.zeros((2, shape_cap), np.int32)
            hi = np.zeros((2, shape_cap), np.int32)
            lo[0] = np.searchsorted(owner, owners, side="left")
            hi[0] = np.searchsorted(owner, owners, side="right")
            first.from_numpy(lo)
            last.from_numpy(hi)
        for name in POINT_FIELDS:
            _write_half(getattr(self, name), records["point_" + name][:points])
        for name in PAIR_FIELDS:
            _write_half(getattr(self, "m_" + name), records["pair_" + name][:pairs])
        for name in SLOT_FIELDS:
            values = records["slot_" + name][:pairs]
            _write_half(getattr(self, "m_" + name), values.reshape((pairs * MAX_POINTS,) + values.shape[2:]))
        self.parity[None] = 0


def _write_half(field, values: np.ndarray) -> None:
    full = field.to_numpy()
    full[0, : len(values)] = values
    field.from_numpy(full)


# ---------------------------------------------------------------------------- kernels' parts
@ti.func
def _copy_points(st: ti.template(), to_half: ti.i32, to: ti.i32, hist: ti.template(), o: ti.i32):
    st.partner[to_half, to] = hist.partner[o]
    st.feature[to_half, to] = hist.feature[o]
    st.anchor[to_half, to] = hist.anchor[o]
    st.lam_n[to_half, to] = hist.lam_n[o]
    st.lam_t[to_half, to] = hist.lam_t[o]


@ti.func
def _copy_stored_point(st: ti.template(), to_half: ti.i32, to: ti.i32, from_half: ti.i32, o: ti.i32):
    st.partner[to_half, to] = st.partner[from_half, o]
    st.feature[to_half, to] = st.feature[from_half, o]
    st.anchor[to_half, to] = st.anchor[from_half, o]
    st.lam_n[to_half, to] = st.lam_n[from_half, o]
    st.lam_t[to_half, to] = st.lam_t[from_half, o]


@ti.func
def _copy_pair(dst: ti.template(), dst_prefix: ti.template(), dh: ti.i32, to: ti.i32, src: ti.template(),
               src_prefix: ti.template(), sh: ti.i32, o: ti.i32):
    """Manifold ``o`` of half ``sh`` of ``src`` to slot ``to`` of half ``dh`` of ``dst``; the store
    names its fields with the prefix "m_", the cache with none (the same copy serves saving,
    moving within the store and restoring)."""
    for name in ti.static(PAIR_FIELDS):
        to_field, from_field = ti.static(getattr(dst, dst_prefix + name), getattr(src, src_prefix + name))
        to_field[dh, to] = from_field[sh, o]
    for name in ti.static(SLOT_FIELDS):
        to_field, from_field = ti.static(getattr(dst, dst_prefix + name), getattr(src, src_prefix + name))
        for s in ti.static(range(MAX_POINTS)):
            to_field[dh, MAX_POINTS * to + s] = from_field[sh, MAX_POINTS * o + s]


@ti.func
def save_sleepers(st: ti.template(), hist: ti.template(), cache: ti.template(), shapes: ti.template(),
                  asleep: ti.template(), change: ti.template()):
    """Rebuild the store into its other half: the records of every sleeping shape, those of the
    shapes falling asleep now (``change`` = FALLING) taken from this step's history and cache
    half. Call at the end of a step (the cache's parity already handed over), at a kernel's
    top level."""
    old = st.parity[None]
    new = 1 - old
    ch = 1 - cache.parity[None]  # the cache half this step wrote
    n = shapes.dynamic_count[None]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shapes.dynamic_ids[k]
        b = shapes.body[i]
        points, pairs = 0, 0
        if change[b] == FALLING:
            points = hist.shape_last[i] - hist.shape_first[i]
            pairs = cache.last[ch, i] - cache.first[ch, i]
        elif asleep[b]:
            points = st.point_last[old, i] - st.point_first[old, i]
            pairs = st.pair_last[old, i] - st.pair_first[old, i]
        st.point_size[k] = points
        st.pair_size[k] = pairs
    exclusive_scan(st.scanner, st.point_size, st.point_at, n, st.point_total)
    exclusive_scan(st.scanner, st.pair_size, st.pair_at, n, st.pair_total)
    for k in range(n):
        i = shapes.dynamic_ids[k]
        b = shapes.body[i]
        p0, m0 = st.point_at[k], st.pair_at[k]
        points, pairs = st.point_size[k], st.pair_size[k]
        if p0 + points > st.point_capacity or m0 + pairs > st.pair_capacity:
            points, pairs = 0, 0
            ti.atomic_add(st.dropped[None], 1)
        if change[b] == FALLING:
            for j in range(points):
                _copy_points(st, new, p0 + j, hist, hist.shape_first[i] + j)
            for j in range(pairs):
                _copy_pair(st, "m_", new, m0 + j, cache, "", ch, cache.first[ch, i] + j)
        elif asleep[b]:
            for j in range(points):
                _copy_stored_point(st, new, p0 + j, old, st.point_first[old, i] + j)
            for j in range(pairs):
                _copy_pair(st, "m_", new, m0 + j, st, "m_", old, st.pair_first[old, i] + j)
        st.point_first[new, i] = p0
        st.point_last[new, i] = p0 + points
        st.pair_first[new, i] = m0
        st.pair_last[new, i] = m0 + pairs
    st.parity[None] = new


@ti.func
def restore_wakers(st: ti.template(), hist: ti.template(), cache: ti.template(), shapes: ti.template(),
                   awake: ti.template(), change: ti.template()):
    """Append the stored records of the shapes waking now (``change`` = WAKING) to the history
    and to the cache half the next narrowphase reads, and point their ranges at them (empty
    when they do not fit). ``awake``: the lists from before this wake, whose shapes' ranges
    mark the used part of that half. Call at a kernel's top level, between steps or between a
    narrowphase and its redo (with the cache's parity handed back)."""
    h = st.parity[None]
    ch = 1 - cache.parity[None]
    ti.loop_config(serialize=True)
    for _ in range(1):
        end = 0
        for k in range(awake.shape_count[None]):
            end = ti.max(end, cache.last[ch, awake.shape_ids[k]])
        st.pair_end[None] = end
    n = shapes.dynamic_count[None]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shapes.dynamic_ids[k]
        points, pairs = 0, 0
        if change[shapes.body[i]] == WAKING:
            points = st.point_last[h, i] - st.point_first[h, i]
            pairs = st.pair_last[h, i] - st.pair_first[h, i]
        st.point_size[k] = points
        st.pair_size[k] = pairs
    exclusive_scan(st.scanner, st.point_size, st.point_at, n, st.point_total)
    exclusive_scan(st.scanner, st.pair_size, st.pair_at, n, st.pair_total)
    point_base = hist.count[None]
    pair_base = st.pair_end[None]
    for k in range(n):
        i = shapes.dynamic_ids[k]
        if change[shapes.body[i]] == WAKING:
            p0 = point_base + st.point_at[k]
            m0 = pair_base + st.pair_at[k]
            points, pairs = st.point_size[k], st.pair_size[k]
            if p0 + points > hist.capacity:
                points = 0
            if m0 + pairs > cache.partner.shape[1]:
                pairs = 0
            for j in range(points):
                o = st.point_first[h, i] + j
                q = p0 + j
                hist.partner[q] = st.partner[h, o]
                hist.feature[q] = st.feature[h, o]
                hist.anchor[q] = st.anchor[h, o]
                hist.lam_n[q] = st.lam_n[h, o]
                hist.lam_t[q] = st.lam_t[h, o]
            for j in range(pairs):
                _copy_pair(cache, "", ch, m0 + j, st, "m_", h, st.pair_first[h, i] + j)
            hist.shape_first[i] = p0
            hist.shape_last[i] = p0 + points
            cache.first[ch, i] = m0
            cache.last[ch, i] = m0 + pairs
    hist.count[None] = ti.min(point_base + st.point_total[None], hist.capacity)
