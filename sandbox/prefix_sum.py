"""Deterministic exclusive prefix sum (and short-range sort) over i32 fields, the same code on CPU and CUDA.

Taichi's ``PrefixSumExecutor`` supports CUDA/Vulkan only (apis.md 4.4), so on CUDA we
scan in three loops: per-block sums in parallel, a short serial scan over the
block sums, then each block scanned serially from its offset. With 256-element
blocks the serial middle loop is ~n/256 long, which keeps it cheap on a GPU,
and integer addition makes the result independent of thread scheduling.
"""


import taichi as ti

from .backend import serialize_light_loops

BLOCK = 256


@ti.func
def sort_range(values: ti.template(), start: ti.i32, end: ti.i32):
    """Insertion sort of values[start:end] in place: the short per-bucket / per-body lists
    that parallel fills leave in thread order are put in a fixed order (determinism)."""
    for u in range(start + 1, end):
        v = values[u]
        w = u - 1
        while w >= start and values[w] > v:
            values[w + 1] = values[w]
            w -= 1
        values[w + 1] = v


@ti.data_oriented
class Scanner:
    """Scratch for scans of up to ``capacity`` elements."""

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.block_sum = ti.field(ti.i32, max(1, (capacity + BLOCK - 1) // BLOCK + 1))


@ti.func
def exclusive_scan(scan: ti.template(), src: ti.template(), dst: ti.template(), n: ti.i32, total: ti.template(),
                   active: ti.i32 = 1):
    """dst[i] = sum(src[:i]) for i < n, dst[n] = total[None] = sum(src[:n]).

    Must be called at the top level of a kernel (it contains top-level loops). On the CPU
    it is one loop on the launching thread: a few microseconds, where each parallel loop
    would cost a thread-pool dispatch (backend.serialize_light_loops). ``active`` = 0 runs its
    loops zero times and leaves ``dst`` and ``total`` as they were (a grid kept from last step).
    """
    if ti.static(serialize_light_loops()):
        ti.loop_config(serialize=True)
        for _ in range(active):
            run = 0
            for k in range(n):
                v = src[k]
                dst[k] = run
                run += v
            total[None] = run
            dst[n] = run
    else:
        _blocked_scan(scan, src, dst, n, total, active)


@ti.func
def _blocked_scan(scan: ti.template(), src: ti.template(), dst: ti.template(), n: ti.i32, total: ti.template(),
                  active: ti.i32 = 1):
    blocks = (n + BLOCK - 1) // BLOCK * active
    for blk in range(blocks):
        s = 0
        for k in range(blk * BLOCK, ti.min((blk + 1) * BLOCK, n)):
            s += src[k]
        scan.block_sum[blk] = s
    for _ in range(active):
        run = 0
        for blk in range(blocks):
            v = scan.block_sum[blk]
            scan.block_sum[blk] = run
            run += v
        total[None] = run
        dst[n] = run
    for blk in range(blocks):
        run = scan.block_sum[blk]
        for k in range(blk * BLOCK, ti.min((blk + 1) * BLOCK, n)):
            v = src[k]
            dst[k] = run
            run += v
