"""The backend: the CPU's thread placement (backend.pin_cpu_workers), and test worlds that follow the
session's backend (tests/helpers.TEST_ARCH)."""

import os
from pathlib import Path

import pytest

from sandbox import backend


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or os.environ.get("SANDBOX_PIN_THREADS") == "0",
                    reason="needs Linux and pinning on")
def test_taichi_workers_are_pinned_one_per_cpu():
    from taichi.lang import impl

    if backend.active_arch() != "cpu":
        pytest.skip("the session runs on CUDA")
    workers = int(impl.current_cfg().cpu_max_num_threads)
    if workers < 2 or len(os.sched_getaffinity(0)) != workers:
        pytest.skip("pinning applies when Taichi runs one worker per allowed CPU")
    cpus = backend.pinned_cpus()
    assert len(cpus) == workers and len(set(cpus)) == workers
    single = [os.sched_getaffinity(int(t)) for t in os.listdir("/proc/self/task")]
    pinned = sorted(next(iter(a)) for a in single if len(a) == 1)
    assert pinned == sorted(cpus)  # exactly the workers, one CPU each; nothing else touched


CPU_BOUND_TESTS = {"state_hashes.py", "test_dispatch.py", "test_backend.py"}
"""Test files that mean the CPU: bitwise state hashes and the CPU loop dispatch (they skip in a
session on another backend)."""


def test_test_worlds_follow_the_session_arch():
    """``SANDBOX_TEST_ARCH=cuda pytest`` must run the suite on CUDA: a world pinned to ``cpu``
    in a CUDA session raises at once (on the first GPU run, 187 tests failed that way)."""
    tests = Path(__file__).parent
    pinned = [f"{p.relative_to(tests)}:{n}" for p in sorted(tests.rglob("*.py")) if p.name not in CPU_BOUND_TESTS
              for n, line in enumerate(p.read_text().splitlines(), 1)
              if 'arch="cpu"' in line]
    assert not pinned, f"use arch=TEST_ARCH (tests/helpers.py): {pinned}"


def test_the_kernel_cache_may_outgrow_taichis_default():
    """The shipped scenes' kernels (102 MB for the 31 quick state-hash cases) fit the offline
    cache, so a process's exit evicts none of them (backend.OFFLINE_CACHE_BYTES); a cap set in
    the environment wins."""
    from taichi.lang import impl

    cap = impl.current_cfg().offline_cache_max_size_of_files
    asked = os.environ.get("TI_OFFLINE_CACHE_MAX_SIZE_OF_FILES")
    assert cap == (int(asked) if asked else backend.OFFLINE_CACHE_BYTES)
