"""Prefix sums and the short-range sort (sandbox/prefix_sum.py) against numpy.

Integers only: every result must be exact, whatever the threads did. Both scans are tested:
the one-loop scan the CPU runs (``exclusive_scan``) and the blocked three-loop scan CUDA runs
(``_blocked_scan``, run here on the CPU, where its loops are parallel too), at sizes around
the block size and far past it.
"""

import numpy as np
import pytest
import taichi as ti

from sandbox import prefix_sum

CAPACITY = 1 << 17
SIZES = [0, 1, 2, 255, 256, 257, 1000, 4097, CAPACITY - 1]
"""Empty, single, below / at / above one block of 256, not powers of two, and large (512 blocks)."""


@ti.kernel
def _scan(scanner: ti.template(), src: ti.template(), dst: ti.template(), n: ti.i32, total: ti.template(),
          active: ti.i32):
    prefix_sum.exclusive_scan(scanner, src, dst, n, total, active)


@ti.kernel
def _blocked(scanner: ti.template(), src: ti.template(), dst: ti.template(), n: ti.i32, total: ti.template(),
             active: ti.i32):
    prefix_sum._blocked_scan(scanner, src, dst, n, total, active)


@ti.kernel
def _sort_ranges(values: ti.template(), starts: ti.template(), ranges: ti.i32):
    for r in range(ranges):  # parallel: ranges are disjoint
        prefix_sum.sort_range(values, starts[r], starts[r + 1])


@pytest.fixture(scope="module")
def fields():
    return {
        "scanner": prefix_sum.Scanner(CAPACITY),
        "src": ti.field(ti.i32, CAPACITY),
        "dst": ti.field(ti.i32, CAPACITY + 1),
        "total": ti.field(ti.i32, ()),
    }


@pytest.mark.parametrize("kernel", [_scan, _blocked], ids=["cpu-scan", "blocked-scan"])
@pytest.mark.parametrize("n", SIZES)
def test_exclusive_scan_matches_numpy(fields, kernel, n):
    rng = np.random.default_rng(n)
    src = np.zeros(CAPACITY, np.int32)
    src[:n] = rng.integers(0, 100, n)  # counts, as the engine scans (sum < 2^31)
    src[n:] = 7  # past n: must not be read
    fields["src"].from_numpy(src)
    fields["dst"].from_numpy(np.full(CAPACITY + 1, -1, np.int32))
    fields["total"][None] = -1
    kernel(fields["scanner"], fields["src"], fields["dst"], n, fields["total"], 1)
    dst = fields["dst"].to_numpy()
    expected = np.concatenate([[0], np.cumsum(src[:n], dtype=np.int64)])
    np.testing.assert_array_equal(dst[: n + 1], expected)  # dst[n] is the total
    assert fields["total"][None] == expected[-1]
    assert np.all(dst[n + 1:] == -1)  # nothing written past n


@pytest.mark.parametrize("kernel", [_scan, _blocked], ids=["cpu-scan", "blocked-scan"])
def test_an_inactive_scan_writes_nothing(fields, kernel):
    """``active`` 0 (a grid kept from the step before, broadphase.py): the last scan's output stays."""
    n = 1000
    fields["src"].from_numpy(np.full(CAPACITY, 3, np.int32))
    fields["dst"].from_numpy(np.arange(CAPACITY + 1, dtype=np.int32))
    fields["total"][None] = -5
    kernel(fields["scanner"], fields["src"], fields["dst"], n, fields["total"], 0)
    np.testing.assert_array_equal(fields["dst"].to_numpy(), np.arange(CAPACITY + 1, dtype=np.int32))
    assert fields["total"][None] == -5


def test_sort_range_sorts_each_range_and_nothing_else():
    """Ranges of length 0, 1, 2 and up to 300 (a crowded grid bucket), with duplicates, each
    sorted in place; values outside every range stay where they were."""
    rng = np.random.default_rng(3)
    lengths = np.array([0, 1, 2, 0, 5, 17, 300, 3, 64, 1, 129])
    starts = np.concatenate([[4], 4 + np.cumsum(lengths)]).astype(np.int32)  # the first 4 values are outside
    size = int(starts[-1]) + 4
    values = rng.integers(-50, 50, size).astype(np.int32)
    v = ti.field(ti.i32, size)
    s = ti.field(ti.i32, len(starts))
    v.from_numpy(values)
    s.from_numpy(starts)
    _sort_ranges(v, s, len(lengths))
    got = v.to_numpy()
    expected = values.copy()
    for a, b in zip(starts[:-1], starts[1:]):
        expected[a:b] = np.sort(values[a:b])
    np.testing.assert_array_equal(got, expected)
