"""The thread team (sandbox/solvers/team.py) on a toy phase sequence, no World.

Every phase's item k reads items k - 1 and k + 1 of the previous phase, so a member that
started a phase before the last one was finished would read a stale value; integers make
the expected result exact. Members claim chunks of each phase (``next_chunk``), report
them done (``finish``) and wait for the phase (``wait``), as ``team_loop.iterate_shared``
does. A team of one, of two (Taichi's threads here) and of three (more members than
threads: one starts only after another has run every phase) must give the bits of the
loop run in order, and do every item exactly once.
"""

import numpy as np
import pytest
import taichi as ti

from sandbox.solvers import team as tm

ITEMS = 5000  # ~78 chunks of 64 per phase, shared between the members
PHASES = 24
MODULUS = 1_000_003  # keeps the integers small; any change of order changes the result


@ti.kernel
def _walk(team: ti.template(), x: ti.template(), done: ti.template(), n: ti.i32, phases: ti.i32, members: ti.i32):
    tm.reset_loop(team, phases * members)
    for i in range(members * tm.TASK_ITEMS):
        if i % tm.TASK_ITEMS == 0:
            member = i // tm.TASK_ITEMS
            for p in range(phases):
                lo, hi, j = tm.next_chunk(team, p, n, member, members, 0)
                while lo < hi:
                    for k in range(lo, hi):
                        left = x[p, (k + n - 1) % n]
                        right = x[p, (k + 1) % n]
                        x[p + 1, k] = (left + 3 * right + k + p) % MODULUS
                        ti.atomic_add(done[p, k], 1)
                    tm.finish(team, p, hi - lo)
                    lo, hi, j = tm.next_chunk(team, p, n, member, members, j)
                tm.wait(team, p, n)


def _in_order(start: np.ndarray) -> np.ndarray:
    x = np.zeros((PHASES + 1, ITEMS), np.int64)
    x[0] = start
    k = np.arange(ITEMS)
    for p in range(PHASES):
        x[p + 1] = (np.roll(x[p], 1) + 3 * np.roll(x[p], -1) + k + p) % MODULUS
    return x


@pytest.fixture(scope="module")
def fields():
    return ti.field(ti.i32, (PHASES + 1, ITEMS)), ti.field(ti.i32, (PHASES, ITEMS))


@pytest.mark.parametrize("members", [1, 2, 3])
def test_team_walks_the_phases_in_order_and_does_every_item_once(fields, members):
    x, done = fields
    start = np.random.default_rng(members).integers(0, MODULUS, ITEMS)
    values = np.zeros((PHASES + 1, ITEMS), np.int32)
    values[0] = start
    x.from_numpy(values)
    done.fill(0)
    _walk(tm.team_for(PHASES, members), x, done, ITEMS, PHASES, members)
    np.testing.assert_array_equal(done.to_numpy(), 1)
    np.testing.assert_array_equal(x.to_numpy(), _in_order(start))


def test_team_counters_cover_the_phases_of_every_member():
    """``team_for`` gives one pooled Team per power-of-two class, large enough for
    phases x members counters (iterate_shared clears every counter of its Team)."""
    small = tm.team_for(3, 2)
    assert small is tm.team_for(10, 2)  # the same class: the same Team, no new kernel
    big = tm.team_for(700, 3)
    assert big.claimed.shape[0] >= 2100 and big.finished.shape[0] >= 2100
    assert big is not small
