"""A kernel launched step after step with the same arguments, at the cost of the launch.

Every call of a ``@ti.kernel`` first works out, in Python, which compiled instance its
template arguments select (an ``isinstance`` chain per argument, a data-oriented object's
attribute hook, a key built and looked up) and then fills a launch context: ~12 us a call for
``step_kernels``' kernels on the 2-vCPU VMs here, and ~26 us for the pyramid's solve launch,
against ~130 us for a whole 20-box step (docs/bench.md, "Twenty-second pass"). A step calls the
same two kernels with the same objects every time, so ``repeat_launch`` remembers the instance
its last call selected and, when the next call passes the very same objects, launches that
instance directly: the same compiled code, so the same bits. Any other call takes Taichi's
public path and becomes the one remembered.

The direct launch uses Taichi 1.7's Python-side kernel objects (``Kernel.compiled_kernels``,
``make_launch_context``, ``Program.compile_kernel`` / ``launch_kernel``), the calls its own
``Kernel.launch_kernel`` makes; should a Taichi version lack them, every call takes the public
path (the same fallback as host_counters.py).
"""

from __future__ import annotations

import functools
import weakref

from taichi.lang import impl
from taichi.lang.enums import AutodiffMode
from taichi.lang.exception import handle_exception_from_cpp
from taichi.lang.util import cook_dtype
from taichi.types import primitive_types, template
from taichi.types.utils import is_signed


def _held(value):
    """What the remembered call keeps of an argument: a weak reference where the object takes
    one (a world's buffers are not kept alive by a launch), else the value itself."""
    if type(value).__weakrefoffset__:
        return weakref.ref(value)
    return value


def _same(held, value) -> bool:
    if type(held) is weakref.ref:
        return held() is value
    return held is value


class RepeatedKernel:
    """Calls ``kernel`` (a ``@ti.kernel`` of positional arguments, no return value) as the
    kernel itself would; see the module docstring."""

    def __init__(self, kernel):
        functools.update_wrapper(self, kernel)
        self.kernel = kernel
        self._primal = getattr(kernel, "_primal", None)
        self._setters = self._plan(self._primal)
        self._held = None  # the remembered call's arguments (``_held``)
        self._instance = None  # its compiled kernel instance
        self._prog = None  # and the Taichi program that holds it (ti.reset / ti.init make another)

    @staticmethod
    def _plan(primal):
        """(argument position, launch-context slot, setter name, cast) of each non-template
        argument (32-bit signed integers and floats), or None where a direct launch is not possible
        (another argument type, a return value, autodiff, a Taichi without these attributes)."""
        try:
            if primal is None or primal.return_type is not None or primal.autodiff_mode != AutodiffMode.NONE:
                return None
            setters, slot = [], 0
            for position, argument in enumerate(primal.arguments):
                anno = argument.annotation
                if isinstance(anno, template):
                    continue
                if id(anno) in primitive_types.real_type_ids:
                    setters.append((position, (slot,), "set_arg_float", float))
                elif id(anno) in primitive_types.integer_type_ids and is_signed(cook_dtype(anno)):
                    setters.append((position, (slot,), "set_arg_int", int))
                else:
                    return None
                slot += 1
            return tuple(setters)
        except Exception:  # another Taichi version: the public path
            return None

    def __call__(self, *args):
        held = self._held
        if held is not None and len(args) == len(held) and all(map(_same, held, args)):
            runtime = impl.get_runtime()
            if runtime.prog is self._prog and runtime.target_tape is None and runtime.fwd_mode_manager is None:
                self._launch(runtime, args)
                return None
        result = self.kernel(*args)
        self._remember(args)
        return result

    def _launch(self, runtime, args) -> None:
        runtime.materialize()  # as every kernel call does: fields declared since are placed first
        instance = self._instance
        context = instance.make_launch_context()
        for position, slot, setter, cast in self._setters:
            getattr(context, setter)(slot, cast(args[position]))
        prog = runtime.prog
        try:
            prog.launch_kernel(prog.compile_kernel(prog.config(), prog.get_device_caps(), instance), context)
        except Exception as exc:
            raise handle_exception_from_cpp(exc) from None

    def _remember(self, args) -> None:
        """After a public call: the instance it launched, for the next call with the same objects."""
        self._held = None
        primal = self._primal
        if self._setters is None or primal.has_print or len(args) != len(primal.arguments):
            return
        try:
            instance = primal.compiled_kernels[primal.ensure_compiled(*args)]
            if not hasattr(instance, "make_launch_context"):
                return
        except Exception:
            return
        self._instance = instance
        self._prog = impl.get_runtime().prog
        self._held = tuple(map(_held, args))


def repeat_launch(kernel) -> RepeatedKernel:
    """``kernel`` as a RepeatedKernel (a decorator above ``@ti.kernel``)."""
    return RepeatedKernel(kernel)
