"""Broadphase: world AABBs and a spatial hash grid built by counting sort, in expected O(n) and
in a deterministic order (the candidate pairs: pair_search.py).

Dynamic shapes go into a hashed uniform grid, built in every step whose bounds changed (count
cells per shape, scan, write entries, count per bucket, scan, fill, then sort each bucket
by shape id so that the order never depends on thread timing). Static shapes
(mesh triangles, static bodies) sit in a second grid built once on the host
(static_grid.py), so a 8192-triangle terrain costs only the cells a body overlaps.
Planes are tested against every dynamic shape (there are a handful).

Pair reuse (Box2D's and Rapier's enlarged bounds): a dynamic shape enters the grid with its
bounds grown by ``Settings.pair_reuse_margin`` (``aabb_min`` / ``aabb_max`` hold these enlarged
bounds), refitted only when its bounds for the step leave them or are four margins looser than
fitted (a fast body that slowed); pair_search.py says which shapes then search again. A step in
which no shape refits keeps last step's grid, which a build from the same bounds would remake bit
for bit, and which no shape then searches: a settled pile pays only for its bounds (the build was
~0.29 ms of a ~5-7 ms step of the settled 1000-box pile on the 2-core VM, a loop on one thread).
"""


import numpy as np
import taichi as ti

from .awake import shape_id, shape_total
from .backend import serialize_light_loops
from .field_upload import write_rows
from .integrate import ERR_BOUNDS
from .math3d import mat_mul, mat_vec, norm, quat_rotate, quat_to_mat
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
"""Partners a shape keeps from the counting pass (pair_search.find_pairs); a shape with more is
enumerated a second time to write them. 16 covers a dense box pile (mean ~4, max ~12)."""


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
        # shapes that refitted their enlarged bounds this step (pair reuse): the grid is built while
        # above 0; pair_search._choose_searches reads the count and clears it
        self.refits = ti.field(ti.i32, ())
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
def cell_coord(x: vec3, cell: ti.f32) -> ivec3:
    g = x / cell
    c = ivec3(0)
    for k in ti.static(range(3)):
        if g[k] == g[k]:  # NaN stays at cell 0 (the step is rejected by the finite guard)
            c[k] = ti.cast(ti.floor(ti.min(ti.max(g[k], -MAX_CELLS_PER_AXIS), MAX_CELLS_PER_AXIS)), ti.i32)
    return c


@ti.func
def cell_range(lo: vec3, hi: vec3, cell: ti.f32):
    return cell_coord(lo, cell), cell_coord(hi, cell)


@ti.func
def _fits_grid(lo: vec3, hi: vec3, cell: ti.f32) -> ti.i32:
    a, b = cell_range(lo, hi, cell)
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
                ti.atomic_add(bp.refits[None], 1)
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
        a, b = cell_range(lo, hi, cell)
        d = b - a + 1
        bp.cell_count[k] = d[0] * d[1] * d[2]
    # the rest fills the grid; with every shape's enlarged bounds kept and its pair list valid,
    # last step's grid is this step's, and no shape searches it (pair_search.py): skipped
    exclusive_scan(bp.scanner, bp.cell_count, bp.entry_start, n, bp.entry_total, _grid_changed(bp))
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for h in range(bp.hash_size * _grid_changed(bp)):
        bp.bucket_count[h] = 0
        bp.bucket_fill[h] = 0
    mask = bp.hash_size - 1
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n * _grid_changed(bp)):
        i = shape_id(shapes, awake, k)
        a, b = cell_range(bp.aabb_min[i], bp.aabb_max[i], cell)
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
    exclusive_scan(bp.scanner, bp.bucket_count, bp.bucket_start, bp.hash_size, bp.bucket_total, _grid_changed(bp))
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for e in range(ti.min(bp.entry_total[None], bp.entry_capacity) * _grid_changed(bp)):
        h = bp.entry_bucket[e]
        slot = bp.bucket_start[h] + ti.atomic_add(bp.bucket_fill[h], 1)
        bp.sorted_shape[slot] = bp.entry_shape[e]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for h in range(bp.hash_size * _grid_changed(bp)):
        e0 = bp.bucket_start[h]
        e1 = ti.min(bp.bucket_start[h + 1], bp.entry_capacity)
        sort_range(bp.sorted_shape, e0, e1)  # the fill is in thread order
        for e in range(e0, e1):
            j = bp.sorted_shape[e]
            bp.sorted_lo[e] = bp.aabb_min[j]
            bp.sorted_hi[e] = bp.aabb_max[j]
            bp.sorted_body[e] = shapes.body[j]
            bp.sorted_cell_lo[e] = cell_coord(bp.aabb_min[j], cell)


@ti.func
def pair_lists_stale(bp: ti.template()) -> ti.i32:
    """1: last step's pair lists cannot be kept (a new buffer, world or awake set, ``listed`` 0, or a
    list that overflowed), so every shape searches (pair_search.py) and the grid is built."""
    return ti.cast(bp.listed[None] == 0 or bp.pair_total[None] > bp.pair_capacity, ti.i32)


@ti.func
def _grid_changed(bp: ti.template()) -> ti.i32:
    """1: this step builds the grid (a shape refitted, or pair lists that cannot be kept); always
    without pair reuse."""
    changed = 1
    if ti.static(bp.reuses_pairs):
        changed = ti.max(ti.min(bp.refits[None], 1), pair_lists_stale(bp))
    return changed


@ti.kernel
def build_dynamic_grid(bp: ti.template(), shapes: ti.template(), bodies: ti.template(), margin: ti.f32,
                       reuse_margin: ti.f32, dt: ti.f32, speculative: ti.template(), err: ti.template(),
                       awake: ti.template(), dispatch: ti.template()):
    build_dynamic_grid_loops(bp, shapes, bodies, margin, reuse_margin, dt, speculative, err, awake, dispatch)
