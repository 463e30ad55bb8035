"""The CPU backend's thread placement (backend.pin_cpu_workers)."""

import os

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
