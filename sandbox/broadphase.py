"""Broadphase: world AABBs, a spatial hash grid rebuilt per step by counting sort, and
the candidate pair list, in expected O(n) and in a deterministic order.

Dynamic shapes go into a hashed uniform grid rebuilt every step (count cells per
shape, scan, write entries, count per bucket, scan, fill, then sort each bucket
by shape id so that the order never depends on thread timing). Static shapes
(mesh triangles, static bodies) sit in a second grid built once on the host
(static_grid.py), so a 8192-triangle terrain costs only the cells a body overlaps.
Planes are tested against every dynamic shape (there are a handful).

Pairs are enumerated per dynamic shape ``i`` (partners ``j > i`` in the dynamic
grid, static shapes and planes) in two passes, count then write, so each shape's
pairs are contiguous; each shape's partners are sorted by id, then its planes (encoded
as partner ``-1 - plane_index``) by index (``sort_partners``), an order that depends only
on which pairs there are, not on the grid's cells. A pair seen through several cells is kept only in the
cell holding the minimum corner of the two AABBs' intersection (no duplicates, no
hash set).

Pair reuse (Box2D's and Rapier's enlarged bounds): a dynamic shape enters the grid with its
bounds grown by ``Settings.pair_reuse_margin`` (``aabb_min`` / ``aabb_max`` hold these
enlarged bounds), refitted only when its bounds for the step leave them (or they have
grown twice as loose as fitted). Pairs are the overlaps of enlarged bounds, so a shape whose
enlarged bounds and whose partners' did not change has the same partners as last step: it
copies its old list instead of searching the grid. A shape searches again when it was
refitted, when an old partner was, or when a refitted shape of higher id now overlaps it
(``find_pairs_loops``); every shape searches when ``listed`` is 0 (a new world, a changed
awake set) or last step's list overflowed. The extra pairs are farther apart than any margin: the narrowphase finds
no points for them. Since the order is by id, the list is the one a full search gives.
"""


import numpy as np
import taichi as ti

from .awake import shape_id, shape_total
from .backend import serialize_light_loops
from .field_upload import write_rows
from .integrate import ERR_BOUNDS
from .math3d import dot, mat_mul, mat_vec, norm, quat_rotate, quat_to_mat
from .prefix_sum import Scanner, exclusive_scan, sort_range
from .static_grid import hash_table_size

vec3 = ti.math.vec3
ivec3 = ti.math.ivec3

MAX_CELLS_PER_AXIS = 1 << 20
"""Cell coordinates are clamped to +-this: a body very far away shares the border cells
(the exact AABB test still decides), and no float-to-int cast can overflow."""
MAX_SPAN_CELLS = 1 << 16
"""A dynamic shape whose bounds (with its motion over the step) cover more grid cells than
this is an error (ERR_BOUNDS): the solver diverged, or the shape is far larger than
the median one that sets the cell size. Its bounds collapse to a point for the rest of the
step (no loop over millions of cells, no int overflow in the cell count), and the world
restores the last good state and says which body it was."""
PAIRS_PER_SHAPE = 16
"""Partners a shape keeps from the counting pass (``find_pairs``); a shape with more is
enumerated a second time to write them. 16 covers a dense box pile (mean ~4, max ~12)."""

PAIR_SEARCH_STRIDE = 16
"""The pair search's loop visits the shapes in this many interleaved strata (``find_pairs_loops``)."""


@ti.func
def cell_hash(c: ivec3, mask: ti.i32) -> ti.i32:
    h = (c[0] * 73856093) ^ (c[1] * 19349663) ^ (c[2] * 83492791)
    return h & mask


@ti.data_oriented
class Broadphase:
    def __init__(self, shape_capacity: int, entry_capacity: int, pair_capacity: int, static_hash_size: int,
                 static_entry_capacity: int, reuses_pairs: bool = True):
        sc = max(1, shape_capacity)
        self.entry_capacity = max(16, entry_capacity)
        self.pair_capacity = max(16, pair_capacity)
        self.hash_size = hash_table_size(self.entry_capacity)
        self.cell_size = ti.field(ti.f32, ())
        self.aabb_min = ti.Vector.field(3, ti.f32, sc)
        self.aabb_max = ti.Vector.field(3, ti.f32, sc)
        self.cell_count = ti.field(ti.i32, sc + 1)  # per dynamic slot
        self.entry_start = ti.field(ti.i32, sc + 1)
        self.entry_total = ti.field(ti.i32, ())
        self.entry_shape = ti.field(ti.i32, self.entry_capacity)
        self.entry_bucket = ti.field(ti.i32, self.entry_capacity)
        self.sorted_shape = ti.field(ti.i32, self.entry_capacity)
        # each entry's shape bounds and body beside it, so the pair search reads its candidates
        # in order instead of jumping to every candidate's AABB (~half the search's time)
        self.sorted_lo = ti.Vector.field(3, ti.f32, self.entry_capacity)
        self.sorted_hi = ti.Vector.field(3, ti.f32, self.entry_capacity)
        self.sorted_body = ti.field(ti.i32, self.entry_capacity)
        self.sorted_cell_lo = ti.Vector.field(3, ti.i32, self.entry_capacity)  # the cell of its min corner
        self.bucket_count = ti.field(ti.i32, self.hash_size + 1)
        self.bucket_start = ti.field(ti.i32, self.hash_size + 1)
        self.bucket_fill = ti.field(ti.i32, self.hash_size)
        self.bucket_total = ti.field(ti.i32, ())
        self.pair_count = ti.field(ti.i32, sc + 1)  # per dynamic slot
        self.pair_start = ti.field(ti.i32, sc + 1)
        self.pair_total = ti.field(ti.i32, ())
        self.pair_a = ti.field(ti.i32, self.pair_capacity)
        self.pair_b = ti.field(ti.i32, self.pair_capacity)
        self.scratch_b = ti.field(ti.i32, sc * PAIRS_PER_SHAPE)  # partners seen by the counting pass
        # pair reuse (module docstring); a grid that only lists shapes (sleep.py's) has none
        self.reuses_pairs = reuses_pairs
        self.refitted = ti.field(ti.i32, sc)  # by shape id: enlarged bounds fitted again this step
        self.searches = ti.field(ti.i32, sc)  # by shape id: its partners are searched this step
        # 1: last step's list holds every shape's pairs; 0 (a new buffer or world, a new awake set):
        # every shape searches
        self.listed = ti.field(ti.i32, ())
        self.searched = ti.field(ti.i32, ())  # shapes that searched, last pair search
        self.old_b = ti.field(ti.i32, self.pair_capacity if reuses_pairs else 1)  # last step's partners
        self.old_start = ti.field(ti.i32, sc + 1 if reuses_pairs else 1)  # and each slot's first
        self.scanner = Scanner(max(sc, self.hash_size) + 1)
        # static grid, built once per world on the host
        self.static_cell_size = ti.field(ti.f32, ())
        self.static_lo = ti.Vector.field(3, ti.f32, ())  # bounds of every static shape (empty: lo > hi)
        self.static_hi = ti.Vector.field(3, ti.f32, ())
        self.static_hash_size = static_hash_size
        self.static_bucket_start = ti.field(ti.i32, static_hash_size + 1)
        self.static_entries = ti.field(ti.i32, max(1, static_entry_capacity))

    def upload_static_grid(self, grid: dict) -> None:
        """Install a grid from ``static_grid.build_static_grid`` (its hash size must match this
        buffer's)."""
        columns = self.static_grid_columns(grid)
        self.static_cell_size[None] = grid["cell_size"]
        self.static_lo[None] = grid["lo"]
        self.static_hi[None] = grid["hi"]
        write_rows(columns)

    def static_grid_columns(self, grid: dict) -> list:
        """``upload_static_grid``'s tables as field_upload.write_rows columns (build.upload writes
        them with the other buffers' in one launch, and its cell size and bounds in the launch after)."""
        if grid["hash_size"] != self.static_hash_size:
            raise ValueError("static grid was built for another hash size")
        entries = np.zeros(self.static_entries.shape[0], np.int32)
        entries[: len(grid["entries"])] = grid["entries"]
        return [(self.static_bucket_start, 0, grid["bucket_start"].astype(np.int32)), (self.static_entries, 0, entries)]


@ti.func
def shape_world_aabb(shapes: ti.template(), bodies: ti.template(), i: ti.i32, margin: ti.f32):
    """World AABB of shape i grown by ``margin`` on every side."""
    b = shapes.body[i]
    q_body = bodies.rot[b]
    r = mat_mul(quat_to_mat(q_body), quat_to_mat(shapes.local_rot[i]))
    center = bodies.pos[b] + quat_rotate(q_body, shapes.local_pos[i]) + mat_vec(r, shapes.aabb_center[i])
    h = shapes.aabb_half[i]
    ext = vec3(0.0)
    for k in ti.static(range(3)):
        ext[k] = ti.abs(r[k, 0]) * h[0] + ti.abs(r[k, 1]) * h[1] + ti.abs(r[k, 2]) * h[2] + margin
    return center - ext, center + ext


SPECULATIVE_OFF = -1.0
"""The ``speculative`` switch of a world without speculative contacts (compiled away)."""


def speculation(settings) -> float:
    """The collision kernels' ``speculative`` switch (a compile-time float): the speed [m/s] above
    which a body's bounds and margins grow by its motion, or SPECULATIVE_OFF."""
    return float(settings.speculative_speed) if settings.speculative_contacts else SPECULATIVE_OFF


@ti.func
def swept_distance(shapes: ti.template(), bodies: ti.template(), i: ti.i32, h: ti.f32,
                   speculative: ti.template()) -> ti.f32:
    """How far any point of shape i may move in time h [m] (0 for static shapes), when its speed
    bound exceeds ``speculative`` [m/s]; always 0, compiled away, with SPECULATIVE_OFF."""
    d = 0.0
    if ti.static(speculative >= 0.0):
        b = shapes.body[i]
        if bodies.inv_mass[b] > 0.0:
            r = norm(shapes.local_pos[i]) + shapes.bound[i]
            speed = norm(bodies.lin_vel[b]) + norm(bodies.ang_vel[b]) * r
            if speed > speculative:
                d = h * speed
    return d


@ti.func
def compute_all_aabbs_loops(bp: ti.template(), shapes: ti.template(), bodies: ti.template(), margin: ti.f32):
    for i in range(shapes.count[None]):
        lo, hi = shape_world_aabb(shapes, bodies, i, margin)
        bp.aabb_min[i] = lo
        bp.aabb_max[i] = hi


@ti.kernel
def compute_all_aabbs(bp: ti.template(), shapes: ti.template(), bodies: ti.template(), margin: ti.f32):
    compute_all_aabbs_loops(bp, shapes, bodies, margin)


@ti.func
def _cell_coord(x: vec3, cell: ti.f32) -> ivec3:
    g = x / cell
    c = ivec3(0)
    for k in ti.static(range(3)):
        if g[k] == g[k]:  # NaN stays at cell 0 (the step is rejected by the finite guard)
            c[k] = ti.cast(ti.floor(ti.min(ti.max(g[k], -MAX_CELLS_PER_AXIS), MAX_CELLS_PER_AXIS)), ti.i32)
    return c


@ti.func
def _cell_range(lo: vec3, hi: vec3, cell: ti.f32):
    return _cell_coord(lo, cell), _cell_coord(hi, cell)


@ti.func
def _fits_grid(lo: vec3, hi: vec3, cell: ti.f32) -> ti.i32:
    a, b = _cell_range(lo, hi, cell)
    d = ti.cast(b - a + 1, ti.f32)  # float: the product of three spans can overflow an int
    return d[0] * d[1] * d[2] <= MAX_SPAN_CELLS and (lo == lo).all() and (hi == hi).all()


@ti.func
def build_dynamic_grid_loops(bp: ti.template(), shapes: ti.template(), bodies: ti.template(), margin: ti.f32,
                             reuse_margin: ti.f32, dt: ti.f32, speculative: ti.template(), err: ti.template(),
                             awake: ti.template(), dispatch: ti.template()):
    """``dt`` [s] is the step: each AABB also covers where its shape can get to during the step
    (|v| dt + |w| r dt), so fast bodies find their partners and get speculative contacts
    instead of tunnelling. Bounds too large for the grids raise ERR_BOUNDS (MAX_SPAN_CELLS).
    With pair reuse the grid holds the enlarged bounds (``reuse_margin`` [m] more, module
    docstring), refitted where the step's bounds left them.
    ``awake`` (awake.py): the grid holds every dynamic shape, or the listed ones (a sleeping
    world's awake shapes; sleep.py builds the grid of its sleeping shapes with this too)."""
    n = shape_total(shapes, awake)
    cell = bp.cell_size[None]
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for k in range(n):
        i = shape_id(shapes, awake, k)
        lo, hi = shape_world_aabb(shapes, bodies, i, margin + swept_distance(shapes, bodies, i, dt, speculative))
        if not _fits_grid(lo, hi, cell):
            ti.atomic_or(err.flags[None], ERR_BOUNDS)
            ti.atomic_min(err.body[None], shapes.body[i])
            centre = 0.5 * (lo + hi)
            lo = centre
            hi = centre
        if ti.static(bp.reuses_pairs):
            grow = ti.min(reuse_margin, 0.25 * shapes.bound[i])
            fat_lo, fat_hi = bp.aabb_min[i], bp.aabb_max[i]
            inside = (fat_lo <= lo).all() and (hi <= fat_hi).all()
            # bounds left far looser than fitted (a fast body that slowed) are refitted too
            loose = ((fat_hi - fat_lo) - (hi - lo) > 4.0 * grow).any()
            refit = 0
            if bp.listed[None] == 0 or not inside or loose:
                refit = 1
            bp.refitted[i] = refit
            if refit:
                lo -= grow
                hi += grow
                bp.aabb_min[i] = lo
                bp.aabb_max[i] = hi
            else:
                lo = fat_lo
                hi = fat_hi
        else:
            bp.aabb_min[i] = lo
            bp.aabb_max[i] = hi
        a, b = _cell_range(lo, hi, cell)
        d = b - a + 1
        bp.cell_count[k] = d[0] * d[1] * d[2]
    exclusive_scan(bp.scanner, bp.cell_count, bp.entry_start, n, bp.entry_total)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for h in range(bp.hash_size):
        bp.bucket_count[h] = 0
        bp.bucket_fill[h] = 0
    mask = bp.hash_size - 1
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shape_id(shapes, awake, k)
        a, b = _cell_range(bp.aabb_min[i], bp.aabb_max[i], cell)
        e = bp.entry_start[k]
        for x in range(a[0], b[0] + 1):
            for y in range(a[1], b[1] + 1):
                for z in range(a[2], b[2] + 1):
                    if e < bp.entry_capacity:
                        h = cell_hash(ivec3(x, y, z), mask)
                        bp.entry_shape[e] = i
                        bp.entry_bucket[e] = h
                        ti.atomic_add(bp.bucket_count[h], 1)
                    e += 1
    exclusive_scan(bp.scanner, bp.bucket_count, bp.bucket_start, bp.hash_size, bp.bucket_total)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for e in range(ti.min(bp.entry_total[None], bp.entry_capacity)):
        h = bp.entry_bucket[e]
        slot = bp.bucket_start[h] + ti.atomic_add(bp.bucket_fill[h], 1)
        bp.sorted_shape[slot] = bp.entry_shape[e]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for h in range(bp.hash_size):
        e0 = bp.bucket_start[h]
        e1 = ti.min(bp.bucket_start[h + 1], bp.entry_capacity)
        sort_range(bp.sorted_shape, e0, e1)  # the fill is in thread order
        for e in range(e0, e1):
            j = bp.sorted_shape[e]
            bp.sorted_lo[e] = bp.aabb_min[j]
            bp.sorted_hi[e] = bp.aabb_max[j]
            bp.sorted_body[e] = shapes.body[j]
            bp.sorted_cell_lo[e] = _cell_coord(bp.aabb_min[j], cell)


@ti.kernel
def build_dynamic_grid(bp: ti.template(), shapes: ti.template(), bodies: ti.template(), margin: ti.f32,
                       reuse_margin: ti.f32, dt: ti.f32, speculative: ti.template(), err: ti.template(),
                       awake: ti.template(), dispatch: ti.template()):
    build_dynamic_grid_loops(bp, shapes, bodies, margin, reuse_margin, dt, speculative, err, awake, dispatch)


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
    a, b = _cell_range(lo, hi, cell)
    if ti.static(not dynamic):
        # only the cells inside the static shapes' bounds can hold entries: a body far larger
        # than the static cells (or a runaway one) visits those, not millions of empty cells
        a, b = _cell_range(ti.max(lo, bp.static_lo[None]), ti.min(hi, bp.static_hi[None]), cell)
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
                            if (_cell_coord(ti.max(lo, bp.aabb_min[j]), cell) == c).all():
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
        a, b = _cell_range(lo, hi, bp.cell_size[None])
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
    a, b = _cell_range(lo, hi, bp.cell_size[None])
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
    (``searches``, module docstring): all when ``listed`` is 0 or last step's list overflowed."""
    stale = bp.listed[None] == 0 or bp.pair_total[None] > bp.pair_capacity
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for p in range(ti.min(bp.pair_total[None], bp.pair_capacity)):
        bp.old_b[p] = bp.pair_b[p]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n + 1):
        bp.old_start[k] = bp.pair_start[k]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shape_id(shapes, awake, k)
        search = 1 if stale or bp.refitted[i] != 0 else 0
        if search == 0:
            for e in range(bp.old_start[k], bp.old_start[k + 1]):
                j = bp.old_b[e]
                if j >= 0:
                    if bp.refitted[j] != 0:
                        search = 1
        bp.searches[i] = search
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = shape_id(shapes, awake, k)
        if bp.refitted[i] != 0 and not stale:
            _mark_lower_partners(bp, shapes, i)
    bp.listed[None] = 1
    bp.searched[None] = 0


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
