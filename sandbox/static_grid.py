"""The static shapes' hash grid, built once on the host with numpy (statics never move).

Mesh triangles and static bodies' shapes go into a grid of their own (``Broadphase``'s
``static_*`` fields, searched by ``pair_search._visit_grid``): their world bounds are computed
once, the cell is the larger of the dynamic grid's and the statics' median extent, and each
static shape is listed in every cell its bounds cover, bucketed by the same hash the device
uses (``broadphase.cell_hash``) and sorted by shape within a bucket. ``static_entry_count``
sizes the buffer for that before the grid is built.
"""

from __future__ import annotations

import numpy as np

from .scene.rotations import quat_to_matrix


def hash_table_size(n: int) -> int:
    """The power of two at or above ``n`` (at least 16): a hash table's bucket count."""
    return 1 << max(4, int(np.ceil(np.log2(max(2, n)))))


def static_aabbs(host, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """World bounds (lo, hi; one row per shape, zero for dynamic ones) of ``host``'s
    (build.HostWorld) static shapes grown by ``margin``: all at once, by the same matrix
    products as one at a time."""
    a = host.shape_arrays
    lo = np.zeros((len(a["kind"]), 3))
    hi = np.zeros((len(a["kind"]), 3))
    ids = host.static_ids
    if len(ids):
        bodies = a["body"][ids]
        body_rot = quat_to_matrix(host.body_arrays["rot"][bodies])
        r = body_rot @ quat_to_matrix(a["local_rot"][ids])
        c = (host.body_arrays["pos"][bodies] + (body_rot @ a["local_pos"][ids][..., None])[..., 0]
             + (r @ a["aabb_center"][ids][..., None])[..., 0])
        e = (np.abs(r) @ a["aabb_half"][ids][..., None])[..., 0] + margin
        lo[ids], hi[ids] = c - e, c + e
    return lo, hi


def static_cell(aabb_min: np.ndarray, aabb_max: np.ndarray, static_ids: np.ndarray, min_cell: float) -> float:
    """[m] The static grid's cell: the statics' median largest extent, at least ``min_cell``."""
    ext = (aabb_max[static_ids] - aabb_min[static_ids]).max(axis=1)
    return float(max(min_cell, np.median(ext)))


def static_entry_count(host, margin: float) -> int:
    """Entries of ``host``'s static grid: the cells each static shape's bounds cover."""
    if len(host.static_ids) == 0:
        return 0
    lo, hi = static_aabbs(host, margin)
    cell = static_cell(lo, hi, host.static_ids, host.cell_size)
    a = np.floor(lo[host.static_ids] / cell)
    b = np.floor(hi[host.static_ids] / cell)
    return int(np.prod(b - a + 1, axis=1).sum())


def covered_cells(ids: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every cell of each box lo[s] .. hi[s] (inclusive, (N, 3) integer corners), in the order
    of ``ids`` and within a box x-major (the order of a per-box meshgrid, "ij"), with its owner
    from ``ids``: integer array passes, ~18 000 terrain triangles in a few ms."""
    dims = hi - lo + 1
    counts = dims.prod(axis=1)
    owners = np.repeat(ids, counts)
    local = np.arange(int(counts.sum()), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    d = np.repeat(dims, counts, axis=0)
    offset = np.stack([local // (d[:, 1] * d[:, 2]), (local // d[:, 2]) % d[:, 1], local % d[:, 2]], axis=1)
    return np.repeat(lo, counts, axis=0) + offset, owners


def build_static_grid(aabb_min: np.ndarray, aabb_max: np.ndarray, static_ids: np.ndarray, min_cell: float,
                      hash_size: int | None = None) -> dict:
    """Hash grid of the static shapes (``Broadphase.upload_static_grid`` installs it).

    ``hash_size`` (a power of two) may be given to fit a pooled buffer; by default
    it is the next power of two above twice the number of entries."""
    if len(static_ids) == 0:
        hs = hash_size or 16
        return {"hash_size": hs, "cell_size": 1.0, "bucket_start": np.zeros(hs + 1, np.int64),
                "entries": np.zeros(0, np.int64), "lo": (1.0, 1.0, 1.0), "hi": (0.0, 0.0, 0.0)}
    cell = static_cell(aabb_min, aabb_max, static_ids, min_cell)
    lo = np.floor(aabb_min[static_ids] / cell).astype(np.int64)
    hi = np.floor(aabb_max[static_ids] / cell).astype(np.int64)
    cells, owners = covered_cells(np.asarray(static_ids), lo, hi)
    hs = hash_size or hash_table_size(2 * len(cells))
    c32 = cells.astype(np.int32)
    with np.errstate(over="ignore"):  # broadphase.cell_hash's arithmetic, wrapping in int32
        h = (c32[:, 0] * np.int32(73856093)) ^ (c32[:, 1] * np.int32(19349663)) ^ (c32[:, 2] * np.int32(83492791))
    bucket = (h & np.int32(hs - 1)).astype(np.int64)
    order = np.lexsort((owners, bucket))
    counts = np.bincount(bucket, minlength=hs)
    start = np.zeros(hs + 1, np.int64)
    start[1:] = np.cumsum(counts)
    return {"hash_size": hs, "cell_size": cell, "bucket_start": start, "entries": owners[order],
            # padded by a cell: the device's float32 AABBs of the statics may round past these
            "lo": tuple(float(x) - cell for x in aabb_min[static_ids].min(axis=0)),
            "hi": tuple(float(x) + cell for x in aabb_max[static_ids].max(axis=0))}
