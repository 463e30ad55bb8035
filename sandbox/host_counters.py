"""The counters a step reads on the host, at the cost of the read.

A step reads two broadphase totals after the collision (a buffer that overflowed is grown and
the step redone) and the error bits at its end; a sleeping world also its touched mark and three
slots of its status (sleep.py). ``field[None]`` goes through Taichi's
Python-scope checks and key padding on every call: ~4 us a read on the 2-vCPU VMs here,
against ~1 us for the accessor it ends in, when a 20-box step takes ~200 us. The accessor is
public Taichi state (``ScalarField.host_accessors``); should a Taichi version lack it, the
reads fall back to ``field[None]``. (``field.to_numpy()`` of an 8-int field, a kernel with an
external array, took 56-122 us.)
"""

from __future__ import annotations


def scalar_reader(field, index=None):
    """A function of no arguments returning ``field[index]`` (a 0-d field of a materialized
    tree, or element ``index`` of a 1-d one), the same value by the same accessor, without the
    per-call checks."""
    first = field[index]  # also builds the field's host accessors
    try:
        getter = field.host_accessors[0].getter
        key = field._pad_key(index)
        if getter(*key) != first:
            raise ValueError("accessor disagrees")
    except Exception:  # another Taichi version: the public path
        return lambda: field[index]
    return lambda: getter(*key)


class StepCounters:
    """Readers of one buffers.BufferSet's step counters, and the capacities they are checked
    against; made when a world takes its buffers
    (edits.Edits._acquire), after the upload has materialized them."""

    __slots__ = ("entry_total", "pair_total", "error_flags", "entry_capacity", "pair_capacity")

    def __init__(self, buf):
        self.entry_capacity, self.pair_capacity = buf.bp.entry_capacity, buf.bp.pair_capacity
        self.entry_total = scalar_reader(buf.bp.entry_total)
        self.pair_total = scalar_reader(buf.bp.pair_total)
        self.error_flags = scalar_reader(buf.errors.flags)
