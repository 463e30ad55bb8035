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


def test_scalar_arguments_change_freely_and_template_values_compare_by_value(public_calls):
    cells = Cells(4)
    cells.value.from_numpy(np.zeros(4, dtype=np.float32))
    scale_and_shift(cells, 4, 1.0, 2)
    scale_and_shift(cells, 2, 1.0, 2)  # count and factor are scalar arguments: set at each launch
    scale_and_shift(cells, 4, float("3.0") - 2.0, int("2"))  # new objects, equal template value
    assert public_calls.count("scale_and_shift") == 1
    assert cells.value.to_numpy().tolist() == [6.0, 6.0, 4.0, 4.0]
    with pytest.raises(Exception):
        scale_and_shift(cells, 4.0, 1.0, 2)  # a float count: Taichi's own path, and its error
    scale_and_shift(cells, 4, 1.0, 2.0)  # the shift as a float: another template value, another instance
    scale_and_shift(cells, 4, 1.0, 3)
    assert public_calls.count("scale_and_shift") == 4
    assert cells.value.to_numpy().tolist() == [11.0, 11.0, 9.0, 9.0]


def test_other_objects_another_program_or_keywords_take_the_public_path(public_calls):
    a, b = Cells(4), Cells(4)
    scale_and_shift(a, 4, 2.0, 0)
    scale_and_shift(b, 4, 2.0, 0)  # another template object: another instance
    scale_and_shift(b, 4, 2.0, 0)
    assert public_calls.count("scale_and_shift") == 2
    held, instance, _ = scale_and_shift._last
    scale_and_shift._last = (held, instance, object())  # as after ti.reset: the instance belongs to no live program
    scale_and_shift(b, 4, 2.0, 0)
    scale_and_shift(b, 4, 2.0, shift=0)
    assert public_calls.count("scale_and_shift") == 4


@repeat_launch
@ti.kernel
def fill(cells: ti.template(), value: ti.f32):
    for i in range(4):
        cells.value[i] = value


def test_the_wrapper_holds_a_data_oriented_argument_weakly_and_a_dead_one_matches_nothing(public_calls):
    cells = Cells(4)
    fill(cells, 1.0)
    ref = fill._last[0][0]
    assert ref() is cells
    del cells
    gc.collect()
    assert ref() is None  # the wrapper held it weakly (Taichi's own key keeps only a weak one too)
    fill(Cells(4), 1.0)  # a new object, perhaps at the dead one's address
    assert public_calls.count("fill") == 2
    with pytest.raises(Exception):
        fill(None, 1.0)  # not taken for the dead reference: Taichi's own path rejects it


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
