"""repeat_launch: a kernel called again with the same objects launches the instance its last
call compiled, directly; any other call takes Taichi's public path."""

import gc

import numpy as np
import pytest
import taichi as ti
from taichi.lang import kernel_impl

from sandbox.repeat_launch import RepeatedKernel, repeat_launch


@ti.data_oriented
class Cells:
    def __init__(self, n: int):
        self.value = ti.field(ti.f32, n)


@repeat_launch
@ti.kernel
def scale_and_shift(cells: ti.template(), count: ti.i32, factor: ti.f32, shift: ti.template()):
    for i in range(count):
        cells.value[i] = cells.value[i] * factor + shift


@pytest.fixture
def public_calls(monkeypatch):
    """How many calls went through Taichi's own ``Kernel.__call__``."""
    calls = []
    original = kernel_impl.Kernel.__call__

    def counted(self, *args, **kwargs):
        calls.append(self.func.__name__)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(kernel_impl.Kernel, "__call__", counted)
    return calls


def test_a_repeated_call_launches_directly_and_computes_what_the_public_path_computes(public_calls):
    direct, public = Cells(8), Cells(8)
    start = np.arange(8, dtype=np.float32)
    direct.value.from_numpy(start)
    public.value.from_numpy(start)
    count, factor, shift = 6, 1.5, 2  # the same objects every call, as a step passes them
    for _ in range(3):
        scale_and_shift(direct, count, factor, shift)
    assert public_calls.count("scale_and_shift") == 1  # only the first call took Taichi's path
    for _ in range(3):
        scale_and_shift.kernel(public, count, factor, shift)  # the plain kernel, every call public
    assert np.array_equal(direct.value.to_numpy(), public.value.to_numpy())
    assert direct.value.to_numpy()[7] == 7.0  # past ``count``: untouched
    assert direct.value.to_numpy()[1] == ((1.0 * 1.5 + 2) * 1.5 + 2) * 1.5 + 2


def test_other_objects_or_another_program_take_the_public_path_and_are_remembered(public_calls):
    a, b = Cells(4), Cells(4)
    count, factor = 4, 2.0
    scale_and_shift(a, count, factor, 0)
    scale_and_shift(b, count, factor, 0)  # another template object: another instance
    scale_and_shift(b, count, factor, 0)
    scale_and_shift(a, count, 3.0, 0)  # the same values, a new float object: not known to be the same
    assert public_calls.count("scale_and_shift") == 3
    scale_and_shift._prog = object()  # as after ti.reset: the remembered instance belongs to no live program
    scale_and_shift(a, count, 3.0, 0)
    assert public_calls.count("scale_and_shift") == 4


def test_the_remembered_call_does_not_keep_a_data_oriented_argument_alive():
    cells = Cells(4)
    scale_and_shift(cells, 4, 1.0, 0)
    gc.collect()
    ref = scale_and_shift._held[0]
    assert ref() is cells
    del cells
    gc.collect()
    assert ref() is None
    scale_and_shift(Cells(4), 4, 1.0, 0)  # a dead reference is never taken for the new object


def test_a_kernel_it_cannot_launch_directly_always_takes_the_public_path(public_calls):
    @ti.kernel
    def total(cells: ti.template()) -> ti.f32:
        s = 0.0
        for i in range(4):
            s += cells.value[i]
        return s

    wrapped = RepeatedKernel(total)
    cells = Cells(4)
    cells.value.from_numpy(np.ones(4, dtype=np.float32))
    assert wrapped(cells) == 4.0 and wrapped(cells) == 4.0
    assert public_calls.count("total") == 2
