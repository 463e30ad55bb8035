"""How many contact points the CPU's vector units solve at once (solvers/point_lanes.py), and the
layout that lets them.

LLVM turns eight copies of an operation into one 8-wide instruction (its SLP vectorizer) only
when it can prove that the eight values' addresses are consecutive. Taichi computes each field
access's address from the field's root pointer, which it reloads from memory after every store
unless its own IR optimisation (``advanced_optimization``, off here: backend.py) merges the
loads; then no two accesses share a base and nothing vectorizes (measured: benchmarks/
lane_layouts.py). One access to a field whose *element* holds eight points has a single base, so
the data the vector code reads and writes lives in groups: ``lane_group_field(rows, n)`` is a
field of ``n`` points' groups, each a ``rows`` x 8 matrix (row: one quantity, column: one point
of the group). A sweep's last group reads and writes lanes past the point count, so every buffer
it touches holds whole groups (``lane_capacity``)."""

import taichi as ti

LANES = 8
LANE_BITS = 3
assert LANES == 1 << LANE_BITS  # block_adjacency.slot_change splits an index with shifts


def lane_capacity(n: int) -> int:
    """``n`` rounded up to whole groups of ``LANES``."""
    return -(-n // LANES) * LANES


def lane_group_field(rows: int, n: int, sides: int = 0, builder=None):
    """A field of ``n`` points in groups of ``LANES`` (``[group][row, lane]``), or with ``sides`` > 0
    of ``sides`` such sets (``[side, group][row, lane]``). Each of its ``rows`` x 8 entries is a node
    of Taichi's field tree, which holds at most 1024 (``taichi_max_num_snodes``): a set of wide ones
    goes into a tree of its own, ``builder`` (a ``ti.FieldsBuilder``, finalized by the caller)."""
    groups = lane_capacity(max(n, 1)) // LANES
    if builder is None:
        return ti.Matrix.field(rows, LANES, ti.f32, (sides, groups) if sides else groups)
    f = ti.Matrix.field(rows, LANES, ti.f32)
    builder.dense(ti.ij if sides else ti.i, (sides, groups) if sides else groups).place(f)
    return f
