"""Work sharing inside one kernel launch: the CPU threads as a team that walks the
iteration loop's phases together, claiming chunks of each phase and waiting at its end.

Why: on the CPU the iteration loop is one launch (launch overhead bounds small scenes,
solvers/substep.py), and Taichi runs everything nested in a kernel's loop on one thread.
A launch per phase would use every core but pays a thread-pool wake-up per loop
(~50 us on the 2-core VM, ~60 loops a step). Here the threads are woken once per step:
a kernel's top-level loop starts one *member* per thread, and each member runs the whole
phase sequence, taking ``CHUNK`` items of the current phase at a time from shared
counters (its own share first, ``next_chunk``) and, when none are left, waiting until
every item of the phase is finished.

No member ever waits for another member to *arrive*, only for claimed items to be done,
so a team of one (a single thread, or members that Taichi happens to start one after the
other) still runs every phase in order and cannot deadlock. Which member solves which
chunk changes from run to run, but never the result: within a phase every item writes
only its own outputs (a block its slots, a body its state), exactly as in the one-thread
loop, so the bits are those of ``iterate_in_order``. (One shared word more: a biased block
with a fast push stores 1 in its substep's ``fast`` slot; every writer stores the same 1.)

The counters are sequentially consistent integer atomics (Taichi's CPU codegen), which
order each member's plain stores before its "finished" increment and after the "all
finished" read that lets the next phase start.
"""

import taichi as ti

from ..cpu_workers import TASK_ITEMS, cpu_threads  # noqa: F401  (the team's size: one member per worker)

CHUNK = 64
"""Items per claim: large enough that the shared counters are touched rarely (a settled
1000-box pile has ~75 chunks per block phase), small enough to balance two threads."""


@ti.data_oriented
class Team:
    def __init__(self, max_counters: int):
        self.claimed = ti.field(ti.i32, max_counters)  # items handed out, per phase and home range
        self.finished = ti.field(ti.i32, max_counters)  # items done, per phase
        self.fast = ti.field(ti.i32, max_counters)  # 1: a biased phase starting here pushed fast (substep.py)


_teams: dict[int, Team] = {}


def team_for(phases: int, members: int) -> Team:
    """A team with counters for ``phases`` phases of ``members`` home ranges, one per
    power-of-two class and process (a kernel compiles once per Team object; every launch
    resets the counters it uses)."""
    need = max(phases * members, 1)
    size = max(1024, 1 << (need - 1).bit_length())
    if size not in _teams:
        _teams[size] = Team(size)
    return _teams[size]


@ti.func
def reset_loop(team: ti.template(), counters: ti.i32):
    ti.loop_config(serialize=True)  # a few hundred integers: not worth a thread-pool dispatch
    for p in range(counters):
        team.claimed[p] = 0
        team.finished[p] = 0
        team.fast[p] = 0


@ti.func
def next_chunk(team: ti.template(), p: ti.i32, n: ti.i32, member: ti.i32, members: ti.i32, j: ti.i32):
    """The next chunk [lo, hi) of phase p's n items for ``member`` (lo == hi: none left),
    and where to look after it. A member takes chunks of its own home range first (the
    member-th of ``members`` equal ranges) and then helps with the others': the same
    member solves the same blocks and bodies substep after substep, so their rows stay in
    its core's cache, while a member that is late or never starts is covered."""
    lo = 0
    hi = 0
    while j < members:
        r = (member + j) % members
        end = (r + 1) * n // members
        got = r * n // members + ti.atomic_add(team.claimed[p * members + r], CHUNK)
        if got < end:
            lo = got
            hi = ti.min(got + CHUNK, end)
            break
        j += 1
    return lo, hi, j


@ti.func
def finish(team: ti.template(), p: ti.i32, count: ti.i32):
    ti.atomic_add(team.finished[p], count)


@ti.func
def wait(team: ti.template(), p: ti.i32, n: ti.i32):
    """Spin until all n items of phase p are finished: the chunks still out are being
    solved by running members (an atomic read, so the load is never hoisted)."""
    while ti.atomic_add(team.finished[p], 0) < n:
        pass
