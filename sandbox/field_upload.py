"""Rows of many fields written from the host in one launch.

``field.from_numpy`` is a Taichi kernel instance per field (the field is its template
argument), and a process pays for each instance's first call even with a warm offline cache
(its Python AST turned into IR, its machine code loaded: ~10 ms here). A world's build wrote
~45 fields that way, each read back first (``to_numpy``) to keep the rows it did not write: 93
first calls, about a second of a 3.7 s start. ``write_rows`` writes any set of fields' row
ranges in one launch of one kernel instance per set of fields, and touches no other row.
Values are converted to the field's type on the host (float32 or int32, as ``from_numpy``
did), so the fields hold the same bits.
"""

import numpy as np
import taichi as ti
from taichi.lang.matrix import MatrixField

from .backend import serialize_light_loops


def _element_shape(field) -> tuple:
    if isinstance(field, MatrixField):
        return (field.n,) if field.ndim == 1 else (field.n, field.m)
    return ()


def _is_float(field) -> bool:
    return field.dtype in (ti.f32, ti.f64, ti.f16)


@ti.func
def _write_row(field: ti.template(), row: ti.i32, values: ti.template(), base: ti.i32):
    shape = ti.static(_element_shape(field))
    if ti.static(len(shape) == 0):
        field[row] = values[base]
    elif ti.static(len(shape) == 1):
        for a in ti.static(range(shape[0])):
            field[row][a] = values[base + a]
    else:
        for a, c in ti.static(ti.ndrange(shape[0], shape[1])):
            field[row][a, c] = values[base + a * shape[1] + c]


GROUP = 16
"""Columns per unrolled group of ``_write_columns`` (Taichi warns of a static loop longer than 32)."""


@ti.func
def _write_all(fields: ti.template(), meta: ti.template(), floats: ti.template(), ints: ti.template()):
    for g in ti.static(range(0, len(fields), GROUP)):
        for k in ti.static(range(g, min(g + GROUP, len(fields)))):
            width = ti.static(int(np.prod(_element_shape(fields[k]), dtype=np.int64)))
            for i in range(meta[k, 1]):
                if ti.static(_is_float(fields[k])):
                    _write_row(fields[k], meta[k, 0] + i, floats, meta[k, 2] + i * width)
                else:
                    _write_row(fields[k], meta[k, 0] + i, ints, meta[k, 2] + i * width)


@ti.kernel
def _write_columns(fields: ti.template(), meta: ti.types.ndarray(dtype=ti.i32, ndim=2),
                   floats: ti.types.ndarray(dtype=ti.f32, ndim=1), ints: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """Column k: rows meta[k, 0] .. + meta[k, 1] of fields[k], from its values at meta[k, 2].
    On the CPU one serial task writes every column: a parallel loop per column made a module of as
    many tasks, which LLVM compiled (or, from the offline cache, loaded) at twice the cost, for rows
    that take microseconds to write. On a GPU, where one thread would write them one by one, each
    column stays a parallel loop."""
    if ti.static(serialize_light_loops()):
        for _ in range(1):
            _write_all(fields, meta, floats, ints)
    else:
        _write_all(fields, meta, floats, ints)


def write_rows(columns) -> None:
    """``columns``: (field, first row, values) triples; values has one row per field row
    (shape (n,) + the field's element shape). Rows first .. first + n of each field get them."""
    columns = [(f, int(first), np.asarray(v)) for f, first, v in columns]
    if not columns:
        return
    meta = np.zeros((len(columns), 3), np.int32)
    floats, ints, n_float, n_int = [], [], 0, 0
    for k, (field, first, values) in enumerate(columns):
        shape = _element_shape(field)
        n = len(values)
        if values.shape != (n,) + shape:
            raise ValueError(f"rows of shape {values.shape[1:]} for a field of elements {shape}")
        if first < 0 or first + n > field.shape[0]:
            raise ValueError(f"rows {first}..{first + n} outside a field of {field.shape[0]}")
        if _is_float(field):
            meta[k] = first, n, n_float
            floats.append(values.astype(np.float32).ravel())
            n_float += floats[-1].size
        else:
            meta[k] = first, n, n_int
            ints.append(values.astype(np.int32).ravel())
            n_int += ints[-1].size
    flat_f = np.concatenate(floats + [np.zeros(1, np.float32)])  # never empty
    flat_i = np.concatenate(ints + [np.zeros(1, np.int32)])
    _write_columns(tuple(f for f, _, _ in columns), meta, flat_f, flat_i)
