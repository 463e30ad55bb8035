"""The candidate pair list of the broadphase's grids (broadphase.py), in a deterministic order.

Pairs are enumerated per dynamic shape ``i`` (partners ``j > i`` in the dynamic grid, static
shapes and planes) in two passes, count then write, so each shape's pairs are contiguous; each
shape's partners are sorted by id, then its planes (encoded as partner ``-1 - plane_index``) by
index (``sort_partners``), an order that depends only on which pairs there are, not on the grid's
cells. A pair seen through several cells is kept only in the cell holding the minimum corner of
the two AABBs' intersection (no duplicates, no hash set).

Pair reuse: the grid holds enlarged bounds (broadphase.py) and pairs are their overlaps, so a
shape whose enlarged bounds and whose partners' did not change has the same partners as last
step: it copies its old list instead of searching the grid. A shape searches again when it was
refitted, when an old partner was, or when a refitted shape of higher id now overlaps it
(``_choose_searches``); every shape searches when ``listed`` is 0 (a new world, a changed awake
set), when last step's list overflowed, or when more than a third of the shapes refitted
(``SEARCH_ALL_REFITS``). The extra pairs are farther apart than any margin: the
narrowphase finds no points for them. Since the order is by id, the list is the one a full
search gives.
"""

import taichi as ti

from .awake import shape_id, shape_total
from .backend import serialize_light_loops
from .broadphase import PAIRS_PER_SHAPE, cell_coord, cell_hash, cell_range, pair_lists_stale
from .math3d import dot
from .prefix_sum import exclusive_scan

vec3 = ti.math.vec3
ivec3 = ti.math.ivec3

PAIR_SEARCH_STRIDE = 16
"""The pair search's loop visits the shapes in this many interleaved strata (``find_pairs_loops``)."""

SEARCH_ALL_REFITS = 3
"""Every shape searches when more than one in this many refitted (a landing pile, nearly all of
them): marking a refitted shape's partners of lower id is a grid query of its own, on the
launching thread, and costs more than the parallel search of the few shapes it spares. A search
lists what the kept list holds, so the pairs are the same either way."""


@ti.func
def _overlap(bp: ti.template(), i: ti.i32, j: ti.i32) -> ti.i32:
    lo_i, hi_i, lo_j, hi_j = bp.aabb_min[i], bp.aabb_max[i], bp.aabb_min[j], bp.aabb_max[j]
    return (lo_i <= hi_j).all() and (lo_j <= hi_i).all()


COUNT, SCRATCH, WRITE = 0, 1, 2
"""What the enumeration does with a pair: count it only, keep it in the shape's scratch row
(``base`` = the row's start), or write it to the pair list (``base`` = the shape's first pair)."""


@ti.func
def _emit(bp: ti.template(), i: ti.i32, j: ti.i32, base: ti.i32, index: ti.i32, write: ti.template()):
    if ti.static(write == SCRATCH):
        if index < PAIRS_PER_SHAPE:
            bp.scratch_b[base + index] = j
    elif ti.static(write == WRITE):
        if base + index < bp.pair_capacity:
            bp.pair_a[base + index] = i
            bp.pair_b[base + index] = j


@ti.func
def _visit_grid(bp: ti.template(), shapes: ti.template(), i: ti.i32, cell: ti.f32, mask: ti.i32,
                starts: ti.template(), entries: ti.template(), dynamic: ti.template(), base: ti.i32, found: ti.i32,
                write: ti.template()) -> ti.i32:
    """Partners of shape i in one grid: overlapping AABBs, each pair once (in the cell holding
    the minimum corner of the intersection). In the dynamic grid only partners j > i of
    another body count, so each dynamic pair is listed by its lower shape."""
    lo, hi = bp.aabb_min[i], bp.aabb_max[i]
    body_i = shapes.body[i]
    count = found
    a, b = cell_range(lo, hi, cell)
    if ti.static(not dynamic):
        # only the cells inside the static shapes' bounds can hold entries: a body far larger
        # than the static cells (or a runaway one) visits those, not millions of empty cells
        a, b = cell_range(ti.max(lo, bp.static_lo[None]), ti.min(hi, bp.static_hi[None]), cell)
    for x in range(a[0], b[0] + 1):
        for y in range(a[1], b[1] + 1):
            for z in range(a[2], b[2] + 1):
                c = ivec3(x, y, z)
                h = cell_hash(c, mask)
                if ti.static(dynamic):
                    # a bucket is sorted by shape id: walk it from the top down to the first j <= i
                    for back in range(starts[h + 1] - starts[h]):
                        e = starts[h + 1] - 1 - back
                        j = entries[e]
                        if j <= i:
                            break
                        # two cells of one shape can share a bucket: its entries sit side by side
                        duplicate = 0
                        if back > 0:
                            duplicate = entries[e + 1] == j
                        if bp.sorted_body[e] != body_i and duplicate == 0:
                            if (lo <= bp.sorted_hi[e]).all() and (bp.sorted_lo[e] <= hi).all():
                                # the cell of the intersection's min corner, from the corners' cells
                                # (floor is monotonic): integers, no float work per visit
                                if (ti.max(a, bp.sorted_cell_lo[e]) == c).all():
                                    _emit(bp, i, j, base, count, write)
                                    count += 1
                else:
                    for e in range(starts[h], starts[h + 1]):
                        j = entries[e]
                        if _overlap(bp, i, j):
                            if (cell_coord(ti.max(lo, bp.aabb_min[j]), cell) == c).all():
                                _emit(bp, i, j, base, count, write)
                                count += 1
    return count


@ti.func
def _visit_sleepers(bp: ti.template(), grid: ti.template(), i: ti.i32, base: ti.i32, found: ti.i32,
                    write: ti.template()) -> ti.i32:
    """Sleeping partners of awake shape i, from the grid of a sleeping world's sleeping shapes
    (sleep.py builds it with this module's grid code, the same cell size): every overlapping
    one, each once (in the cell holding the intersection's minimum corner). Skipped at the
    cost of one read while nothing sleeps."""
    count = found
    if grid.bucket_total[None] > 0:
        lo, hi = bp.aabb_min[i], bp.aabb_max[i]
        a, b = cell_range(lo, hi, bp.cell_size[None])
        mask = grid.hash_size - 1
        for x in range(a[0], b[0] + 1):
            for y in range(a[1], b[1] + 1):
                for z in range(a[2], b[2] + 1):
                    c = ivec3(x, y, z)
                    h = cell_hash(c, mask)
                    e0 = grid.bucket_start[h]
                    for e in range(e0, grid.bucket_start[h + 1]):
                        j = grid.sorted_shape[e]
                        # a bucket is sorted by shape id: two cells of one shape sit side by side
                        if e == e0 or grid.sorted_shape[e - 1] != j:
                            if (lo <= grid.sorted_hi[e]).all() and (grid.sorted_lo[e] <= hi).all():
                                if (ti.max(a, grid.sorted_cell_lo[e]) == c).all():
                                    _emit(bp, i, j, base, count, write)
                                    count += 1
    return count


@ti.func
def _visit_pairs(bp: ti.template(), shapes: ti.template(), k: ti.i32, base: ti.i32, write: ti.template(),
                 awake: ti.template()) -> ti.i32:
    i = shape_id(shapes, awake, k)
    lo, hi = bp.aabb_min[i], bp.aabb_max[i]
    found = _visit_grid(bp, shapes, i, bp.cell_size[None], bp.hash_size - 1, bp.bucket_start, bp.sorted_shape, True,
                        base, 0, write)
    if ti.static(awake.compact):  # a sleeping world: its sleeping shapes, which only awake ones can wake
        found = _visit_sleepers(bp, awake.grid, i, base, found, write)
    if bp.static_bucket_start[bp.static_hash_size] > 0:  # a static grid with entries (not just planes)
        found = _visit_grid(bp, shapes, i, bp.static_cell_size[None], bp.static_hash_size - 1,
                            bp.static_bucket_start, bp.static_entries, False, base, found, write)
    # planes
    for p in range(shapes.plane_count[None]):
        n = shapes.plane_normal[p]
        center = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        lowest = dot(n, center) - (ti.abs(n[0]) * half[0] + ti.abs(n[1]) * half[1] + ti.abs(n[2]) * half[2])
        if lowest <= shapes.plane_offset[p]:
            _emit(bp, i, -1 - p, base, found, write)
            found += 1
    return found


@ti.func
def _partner_key(j: ti.i32) -> ti.i32:
    """Shapes by id, then planes by index: serial PGS solves a box's ground contact after its
    neighbours', as it did when the planes came last in the grid's order (the kicked 1:1000
    column came to rest only so; docs/bench.md, "Fifteenth pass")."""
    key = j
    if j < 0:
        key = PLANE_KEYS - 1 - j
    return key


PLANE_KEYS = 1 << 30
"""Partner keys from here on are planes' (shape ids stay below it)."""


@ti.func
def sort_partners(partners: ti.template(), start: ti.i32, end: ti.i32):
    """Insertion sort of partners[start:end] by ``_partner_key`` (a shape's few partners)."""
    for u in range(start + 1, end):
        v = partners[u]
        key = _partner_key(v)
        w = u - 1
        while w >= start and _partner_key(partners[w]) > key:
            partners[w + 1] = partners[w]
            w -= 1
        partners[w + 1] = v


@ti.func
def _mark_lower_partners(bp: ti.template(), shapes: ti.template(), i: ti.i32):
    """Refitted shape i's partners of lower id search again: the pair is in their lists."""
    lo, hi = bp.aabb_min[i], bp.aabb_max[i]
    body_i = shapes.body[i]
    a, b = cell_range(lo, hi, bp.cell_size[None])
    mask = bp.hash_size - 1
    for x in range(a[0], b[0] + 1):
        for y in range(a[1], b[1] + 1):
            for z in range(a[2], b[2] + 1):
                h = cell_hash(ivec3(x, y, z), mask)
                for e in range(bp.bucket_start[h], bp.bucket_start[h + 1]):
                    j = bp.sorted_shape[e]
                    if j >= i:  # a bucket is sorted by shape id
                        break
                    if bp.sorted_body[e] != body_i:
                        if (lo <= bp.sorted_hi[e]).all() and (bp.sorted_lo[e] <= hi).all():
                            bp.searches[j] = 1


@ti.func
def _choose_searches(bp: ti.template(), shapes: ti.template(), awake: ti.template(), n: ti.i32):
    """Keep last step's list in ``old_b`` / ``old_start`` and say which shapes search again
    (``searches``, module docstring): all when ``listed`` is 0, when last step's list overflowed, or
    when more than one shape in ``SEARCH_ALL_REFITS`` refitted (``refits``, cleared here)."""
    every = pair_lists_stale(bp)
    if SEARCH_ALL_REFITS * bp.refits[None] > n:
        every = 1
    keep = 1 - every
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for p in range(ti.min(bp.pair_total[None], bp.pair_capacity) * keep):
        bp.old_b[p] = bp.pair_b[p]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range((n + 1) * keep):
        bp.old_start[k] = bp.pair_start[k]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shape_id(shapes, awake, k)
        search = 1 if every or bp.refitted[i] != 0 else 0
        if search == 0:
            for e in range(bp.old_start[k], bp.old_start[k + 1]):
                j = bp.old_b[e]
                if j >= 0:
                    if bp.refitted[j] != 0:
                        search = 1
        bp.searches[i] = search
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n * keep):
        i = shape_id(shapes, awake, k)
        if bp.refitted[i] != 0:
            _mark_lower_partners(bp, shapes, i)
    bp.listed[None] = 1
    bp.searched[None] = 0
    bp.refits[None] = 0


@ti.func
def find_pairs_loops(bp: ti.template(), shapes: ti.template(), awake: ti.template(), dispatch: ti.template()):
    """Count pass (which keeps the first PAIRS_PER_SHAPE partners of each shape in its
    scratch row, sorted), scan, then copy; only a shape with more partners is enumerated again.
    ``awake``: the shapes of the grid (``build_dynamic_grid_loops``) enumerate the pairs. A shape
    that need not search (module docstring) counts and copies its list of last step."""
    n = shape_total(shapes, awake)
    _choose_searches(bp, shapes, awake, n)
    # a shape checks only partners of higher id, so low ids carry most of the work, and
    # Taichi's CPU loop hands each thread one contiguous block of the range: visit the
    # shapes interleaved (t -> k), so every block holds low and high ids alike
    rows = (n + PAIR_SEARCH_STRIDE - 1) // PAIR_SEARCH_STRIDE
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for t in range(rows * PAIR_SEARCH_STRIDE):
        k = (t % PAIR_SEARCH_STRIDE) * rows + t // PAIR_SEARCH_STRIDE
        if k < n:
            i = shape_id(shapes, awake, k)
            if bp.searches[i] != 0:
                cnt = _visit_pairs(bp, shapes, k, k * PAIRS_PER_SHAPE, SCRATCH, awake)
                sort_partners(bp.scratch_b, k * PAIRS_PER_SHAPE, k * PAIRS_PER_SHAPE + ti.min(cnt, PAIRS_PER_SHAPE))
                bp.pair_count[k] = cnt
                ti.atomic_add(bp.searched[None], 1)
            else:
                bp.pair_count[k] = bp.old_start[k + 1] - bp.old_start[k]
    exclusive_scan(bp.scanner, bp.pair_count, bp.pair_start, n, bp.pair_total)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        cnt = bp.pair_count[k]
        base = bp.pair_start[k]
        i = shape_id(shapes, awake, k)
        kept = ti.max(0, ti.min(cnt, bp.pair_capacity - base))
        if bp.searches[i] == 0:
            old = bp.old_start[k]
            for e in range(kept):
                bp.pair_a[base + e] = i
                bp.pair_b[base + e] = bp.old_b[old + e]
        elif cnt <= PAIRS_PER_SHAPE:
            for e in range(kept):
                bp.pair_a[base + e] = i
                bp.pair_b[base + e] = bp.scratch_b[k * PAIRS_PER_SHAPE + e]
        else:
            _visit_pairs(bp, shapes, k, base, WRITE, awake)
            sort_partners(bp.pair_b, base, base + kept)


@ti.kernel
def find_pairs(bp: ti.template(), shapes: ti.template(), awake: ti.template(), dispatch: ti.template()):
    find_pairs_loops(bp, shapes, awake, dispatch)
