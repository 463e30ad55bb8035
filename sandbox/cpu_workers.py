"""Taichi's CPU worker threads: how many run a parallel loop, how a top-level loop hands one
task to each, and pinning each worker to its own CPU.

Both the backend (pinning at ``backend.init``) and the solver team (solvers/team.py, which
starts one member per worker) use these facts; they live here so that neither imports the
other (``backend.init`` imports this module only when it pins, after ``ti.init``).
"""

import os
import threading

import taichi as ti

TASK_ITEMS = 512
"""Items per task of a CPU range-for in Taichi 1.7 (runtime.cpp: adaptive block size
max(512, n / (threads x 32))): a top-level loop over ``members x TASK_ITEMS`` items
starting a member at every multiple of it gives one member per task, i.e. per thread.
Should a Taichi version split it otherwise, the team only gets smaller, never wrong."""


def cpu_threads() -> int:
    """Threads Taichi's CPU runtime runs a parallel loop on (``cpu_max_num_threads``)."""
    from taichi.lang import impl

    return int(impl.current_cfg().cpu_max_num_threads)


def _thread_cpu_ticks() -> dict[int, int]:
    """User + system clock ticks of every thread of this process (Linux /proc)."""
    ticks = {}
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            ticks[int(tid)] = int(fields[11]) + int(fields[12])
        except (OSError, IndexError, ValueError):
            continue
    return ticks


def pin_cpu_workers(tries: int = 6) -> list[int]:
    """Pin each of Taichi's CPU worker threads to its own CPU; returns the CPUs used
    (empty when not done: not Linux, as many workers as CPUs not the case (a process given
    fewer threads shares the machine, and pinning every such process to the same CPUs would
    stack them), or the workers could not be told apart).

    Why: the solver team (solvers/team.py) spins while it waits for a phase to finish, and
    Linux's wake-affine placement now and then puts both workers on the CPU that woke
    them; the two then take turns by time slices, and the iteration loop takes 2.5x as
    long. Measured on the 2-vCPU VM, pile_1000, mass splitting: the loop's p90 was 9.9-11.6
    ms free against 3.8-4.7 ms pinned (median 3.4-4.2 both), and peer_speed's (then peer_pybullet's) median
    ratio 1.12-1.31x free against 1.78-1.82x pinned (runs alternated). Workers are told apart by the
    CPU time they gain while a kernel keeps each of them busy (one task per thread, as the
    team starts its members); nothing else in the process is touched.
    ``SANDBOX_PIN_THREADS=0`` turns it off."""
    if not os.path.isdir("/proc/self/task") or not hasattr(os, "sched_setaffinity"):
        return []
    workers = cpu_threads()
    cpus = sorted(os.sched_getaffinity(0))
    if workers < 2 or len(cpus) != workers:
        return []
    main = threading.get_native_id()
    for _ in range(tries):
        before = _thread_cpu_ticks()
        keep_members_busy(workers * TASK_ITEMS, 15_000_000)  # ~25 ms per member
        after = _thread_cpu_ticks()
        busy = sorted(tid for tid, t in after.items() if tid != main and t - before.get(tid, 0) >= 1)
        if len(busy) == workers:
            try:
                for tid, cpu in zip(busy, cpus):
                    os.sched_setaffinity(tid, {cpu})
            except OSError:  # forbidden, or a thread gone: run unpinned, all of them
                for tid in busy:
                    try:
                        os.sched_setaffinity(tid, set(cpus))
                    except OSError:
                        pass
                return []
            return cpus
    return []


@ti.kernel
def keep_members_busy(items: ti.i32, iterations: ti.i32) -> ti.f32:
    """A top-level loop started like a team (one member per ``TASK_ITEMS``), each member a
    dependent chain of ``iterations`` steps: keeps every CPU worker busy at once, for a
    while, so that ``pin_cpu_workers`` can tell which threads they are."""
    total = 0.0
    for t in range(items):
        if t % TASK_ITEMS == 0:
            x = 1.0
            for _ in range(iterations):
                x = x * 1.0000001 + 1e-7  # grows: no fixed point to stop at, nothing to fold
            total += x
    return total
