"""Taichi backend selection: ``cpu`` | ``cuda`` | ``auto``, one ``ti.init`` per process.

``auto`` picks CUDA only when the driver library loads and reports a device;
the probe goes through ``ctypes`` because ``ti.init(arch=ti.gpu)`` segfaults on a
machine without a GPU (it probes OpenGL first), see docs in apis.md section 4.1.
Worlds created later in the same process share the runtime; asking for a
different arch after the first init is an error rather than a silent reset
that would destroy every live world's fields.
"""

from __future__ import annotations

import ctypes
import os
import threading

from .errors import SandboxError

ARCHES = ("cpu", "cuda", "auto")
LOOPS_ENV = "SANDBOX_LOOPS"
"""``SANDBOX_LOOPS=cuda`` before the first world: a CPU run takes the loop shapes of a CUDA run
(loop_arch), so that the CPU test suite meets what only the GPU's parallel loops would."""
_active: str | None = None
_loop_arch: str | None = None
_owner_thread: int | None = None
_pinned: list[int] = []


def cuda_available() -> bool:
    """True when libcuda loads and reports at least one device."""
    for name in ("libcuda.so.1", "libcuda.so"):
        try:
            lib = ctypes.CDLL(name)
        except OSError:
            continue
        try:
            if lib.cuInit(0) != 0:
                return False
            count = ctypes.c_int(0)
            return lib.cuDeviceGetCount(ctypes.byref(count)) == 0 and count.value > 0
        except AttributeError:
            return False
    return False


def resolve_arch(arch: str) -> str:
    if arch not in ARCHES:
        raise SandboxError(f"unknown arch {arch!r}; choose one of {', '.join(ARCHES)}")
    if arch == "auto":
        return "cuda" if cuda_available() else "cpu"
    if arch == "cuda" and not cuda_available():
        raise SandboxError("arch 'cuda' asked for, but no CUDA device was found; use --arch cpu or auto")
    return arch


def init(arch: str = "auto") -> str:
    """Initialise Taichi once for this process and return the arch in use."""
    global _active, _owner_thread, _loop_arch
    wanted = resolve_arch(arch)
    if _active is not None and threading.get_ident() != _owner_thread:
        # Taichi's LLVM context asserts (and aborts the call with a raw traceback) when
        # another thread compiles: every Taichi call must come from the thread that started it.
        raise SandboxError(f"Taichi was started in thread {_owner_thread} and can only be used from it "
                           f"(this is thread {threading.get_ident()}); run the whole simulation in one thread")
    if _active is not None:
        if wanted != _active and arch != "auto":
            raise SandboxError(
                f"Taichi is already running on {_active} in this process; cannot switch to {wanted}"
            )
        return _active
    loops = _loops_asked(wanted)
    os.environ.setdefault("TI_SKIP_VERSION_CHECK", "ON")
    import taichi as ti

    from .source_positions import memoise_function_sources, memoise_source_positions

    memoise_source_positions()
    memoise_function_sources()

    ti.init(
        arch=ti.cuda if wanted == "cuda" else ti.cpu,
        default_fp=ti.f32,
        log_level=ti.WARN,
        enable_fallback=False,
        random_seed=0,
        # fast_math reorders float operations differently per kernel; keep IEEE
        # semantics so CPU runs are bitwise repeatable and NaN checks are reliable.
        fast_math=False,
        # Taichi's own IR optimisation passes cost ~6x the compile time of the
        # narrowphase kernel (9 s -> 1.5 s on the CI machine) for no measurable
        # run-time gain: LLVM still optimises the generated code.
        advanced_optimization=False,
        **_cache_size(),
    )
    _active = wanted
    _loop_arch = loops
    _owner_thread = threading.get_ident()
    if wanted == "cpu" and os.environ.get("SANDBOX_PIN_THREADS", "1") != "0":
        from .cpu_workers import pin_cpu_workers

        _pinned[:] = pin_cpu_workers()
    return wanted


OFFLINE_CACHE_BYTES = 1 << 30
"""Taichi's offline kernel cache may grow to 1 GiB (Taichi's default: 100 MB). The 31 quick
state-hash cases (every shipped scene with its own solver, three with every solver) compile
102 MB of kernels into an empty cache, so at Taichi's default every process that ends above it
evicts the least recently used quarter, and a scene opened again after a few others compiles
again (~6 s more on its first step; docs/bench.md)."""


def _cache_size() -> dict:
    """``ti.init``'s cache cap, unless ``TI_OFFLINE_CACHE_MAX_SIZE_OF_FILES`` sets one."""
    if os.environ.get("TI_OFFLINE_CACHE_MAX_SIZE_OF_FILES"):
        return {}
    return {"offline_cache_max_size_of_files": OFFLINE_CACHE_BYTES}


def pinned_cpus() -> list[int]:
    """The CPUs Taichi's worker threads were pinned to at init, one each (empty: not pinned)."""
    return list(_pinned)


def active_arch() -> str | None:
    return _active


def _loops_asked(arch: str) -> str:
    asked = os.environ.get(LOOPS_ENV, "")
    if asked not in ("", "cpu", "cuda"):
        raise SandboxError(f"{LOOPS_ENV}={asked!r}: use 'cuda' (a CPU run takes CUDA's loop shapes) or 'cpu' "
                           f"(each arch its own, the default)")
    return "cuda" if arch == "cuda" or asked == "cuda" else "cpu"


def loop_arch() -> str | None:
    """The arch whose loop shapes the kernels take: the active one, or ``cuda`` on the CPU under
    ``SANDBOX_LOOPS=cuda`` (``cpu``, the default, keeps each arch's own). CUDA's shapes: every
    light loop parallel (serialize_light_loops), every heavy loop parallel whatever the world's
    size (dispatch.py), and the iteration loop never the CPU's one or shared launch
    (Schedule.launch: one launch per substep where the schedule has it, else per stage). On the
    CPU they run on Taichi's worker threads, so a loop whose result depends on its order (a race)
    shows there as on a GPU; each shape gives the same bits (tests/test_dispatch.py compares the
    state hashes)."""
    return _loop_arch


def sync() -> None:
    import taichi as ti

    ti.sync()


def serialize_light_loops() -> bool:
    """Compile-time switch for ``ti.loop_config(serialize=...)`` before a *light* loop (a
    copy or clear over bodies, a scan, a short fill: microseconds of work). On the CPU every
    parallel loop is a thread-pool dispatch, ~30-50 us each on the 2-core VM whatever its
    size (benchmarks/loop_dispatch.py), against ~0.3 us for a loop run on the launching
    thread; a step has ~40 such loops. On CUDA they stay parallel (and under loop_arch's
    ``SANDBOX_LOOPS=cuda``)."""
    return _loop_arch == "cpu"


def capacity_ranges() -> bool:
    """Compile-time switch for the loops of a substep launched on its own
    (solvers/substep_loops.py): under CUDA's loop shapes each runs to its buffer's capacity, a
    constant, and every thread compares its index with the count itself, since a range read at
    run time is a single-thread task before the loop, on a GPU a launch of its own. The CPU
    keeps ``range(count)``: there a constant capacity would visit empty slots for nothing."""
    return _loop_arch == "cuda"
