"""Device buffers of a world, pooled per capacity class so kernels compile once per process.

Taichi compiles a kernel once per distinct set of field containers passed to it
as templates. The narrowphase kernel alone takes tens of seconds to compile, so
a second World in the same process must not bring new containers. Every
capacity is rounded up to a power of two (its *class*); a world borrows a
``BufferSet`` of its class from the pool and gives it back on ``close()``, and
the next world of that class reuses the fields and the compiled kernels. The
allocation order is fixed, so Taichi's offline cache also hits across processes.
Unused tail entries are never read: every kernel loops over live counters.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

from .bodies import Bodies
from .broadphase import Broadphase
from .contacts import Contacts
from .impact import ImpactMonitor
from .integrate import ErrorFlags
from .manifold_cache import ManifoldCache
from .metrics import MetricBuffer
from .persistence import ContactHistory
from .shapes import PolytopePool, ShapeTable
from .solvers.block_adjacency import BlockScratch
from .solvers.pgs import Coloring
from .solvers.point_lanes import LaneRows
from .solvers.rows import Rows
from .step_scalars import StepScalars


def capacity_class(n: int, minimum: int = 64) -> int:
    n = max(int(n), minimum)
    return 1 << (n - 1).bit_length()


@dataclass(frozen=True)
class Capacities:
    bodies: int
    shapes: int
    planes: int
    polys: int
    poly_verts: int
    poly_faces: int
    poly_loops: int
    poly_edges: int
    static_hash: int
    static_entries: int
    grid_entries: int
    pairs: int

    @classmethod
    def for_counts(cls, **counts) -> "Capacities":
        minimum = {"planes": 8, "static_hash": 1024}
        return cls(**{k: capacity_class(v, minimum.get(k, 64)) for k, v in counts.items()})

    def covering(self, other: "Capacities") -> "Capacities":
        """The larger of the two classes, field by field (a rebuild never shrinks a world's buffers,
        so removing bodies or fracturing does not recompile the kernels for a smaller class)."""
        return Capacities(**{k: max(v, getattr(other, k)) for k, v in self.__dict__.items()})

    def grown(self, **changes) -> "Capacities":
        values = dict(self.__dict__)
        values.update({k: capacity_class(v) for k, v in changes.items()})
        return Capacities(**values)


class BufferSet:
    """Every Taichi container one world needs; see the module docstring. The fused step kernels
    take it whole as a template argument (step_kernels.py). A plain class, not
    ``ti.data_oriented``: Taichi keys every launch on its template arguments with ~9
    ``isinstance`` checks each, and on a data-oriented object each runs that decorator's Python
    ``__getattribute__`` (~1 us). Taichi then holds a strong reference instead of a weak one,
    which changes nothing: the pool keeps every BufferSet for the life of the process."""

    def __init__(self, caps: Capacities):
        self.caps = caps
        self.bodies = Bodies(caps.bodies)
        self.shapes = ShapeTable(caps.shapes, caps.planes)
        self.pool = PolytopePool(caps.polys, caps.poly_verts, caps.poly_faces, caps.poly_loops, caps.poly_edges)
        self.bp = Broadphase(caps.shapes, caps.grid_entries, caps.pairs, caps.static_hash, caps.static_entries)
        self.contacts = Contacts(caps.pairs, caps.shapes)
        point_capacity = self.contacts.capacity
        self.rows = Rows(point_capacity)
        self.history = ContactHistory(point_capacity, caps.shapes)
        self.blocks = BlockScratch(point_capacity, caps.bodies)
        self.lanes = None  # point_lanes.LaneRows, allocated when this set first runs the CPU team (lane_rows)
        self.coloring = Coloring(caps.pairs, caps.bodies)
        self.impacts = ImpactMonitor(point_capacity, caps.bodies)
        self.errors = ErrorFlags()
        self.scalars = StepScalars()
        self.metrics = MetricBuffer()
        self.manifold_cache = ManifoldCache(caps.pairs, caps.shapes)
        self.islands = None  # islands.Islands, allocated on first use (sleep.islands_of)
        self.sleep = None  # sleep.SleepBuffers, allocated when a world of this class first sleeps

    def lane_rows(self) -> LaneRows:
        """The rows in groups of eight that the CPU team's sweeps read (solvers/point_lanes.py),
        allocated on the first call: ~70 floats a point, 19 a body, and ~710 field nodes (0.08 s to declare on
        the 2-core VM) that a world on CUDA, a small world's one-thread loop and serial PGS never
        touch. Schedule.team calls it before every launch of the team, so no kernel that reads it
        compiles without it; it does so for every schedule the team runs (pgs-colored and block
        mass splitting, whose sweeps do not read the lanes, included), which keeps the rule simple."""
        if self.lanes is None:
            self.lanes = LaneRows(self.contacts.capacity, self.bodies.capacity)
        return self.lanes


_free: dict[Capacities, list[BufferSet]] = {}


def acquire(caps: Capacities) -> BufferSet:
    free = _free.get(caps)
    if free:
        return free.pop()
    return BufferSet(caps)


def release(buffers: BufferSet) -> None:
    _free.setdefault(buffers.caps, []).append(buffers)


def release_on_collect(owner, buffers: BufferSet) -> weakref.finalize:
    """Give ``buffers`` back to the pool when ``owner`` is garbage collected."""
    return weakref.finalize(owner, release, buffers)
