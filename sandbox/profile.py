"""Stage timers. A stage is timed by syncing the device, then reading the clock, so
CUDA's asynchronous launches are not mistaken for speed (house rule 1). Syncing
costs a little, so timing is off unless asked for (benchmarks and the CLI ask).

Two ways to time a step. Stage by stage (``per_stage``, the benchmarks'): every stage its own
kernel launch, the same bits as the fused step but other kernels, which a process compiles
apart from the fused ones (seconds each on the CPU). Launch by launch: the fused step itself,
each of its launches timed under the name of the stage group it spans (``collide`` for
``begin_and_collide``, ``solve`` for a one-launch solve); the web sandbox samples this way,
so a sampled step compiles nothing new and measures the step that runs.
"""

from __future__ import annotations

import time
from collections import defaultdict
from contextlib import contextmanager

import taichi as ti

STAGES = ("integrate_velocities", "broadphase", "narrowphase", "prepare", "iterate", "integrate_positions", "relax")
GROUPS = {
    "collide": ("broadphase", "narrowphase"),
    "solve": ("prepare", "iterate", "relax"),
    "integrate": ("integrate_velocities", "integrate_positions"),
}


class Profiler:
    def __init__(self, enabled: bool = False, per_stage: bool = True):
        self.enabled = enabled
        self.per_stage = per_stage
        self.total_s: dict[str, float] = defaultdict(float)
        self.steps = 0

    @contextmanager
    def stage(self, name: str):
        if not self.enabled:
            yield
            return
        ti.sync()
        t0 = time.perf_counter()
        yield
        ti.sync()
        self.total_s[name] += time.perf_counter() - t0

    def reset(self):
        self.total_s.clear()
        self.steps = 0

    def mean_ms(self) -> dict[str, float]:
        """Mean ms per step for every stage, the three groups and the total. A launch timed under
        a group's name (launch by launch) counts in that group."""
        n = max(1, self.steps)
        stages = {name: 1e3 * self.total_s.get(name, 0.0) / n for name in STAGES}
        launches = {group: 1e3 * self.total_s.get(group, 0.0) / n for group in GROUPS}
        out = dict(stages)
        for group, members in GROUPS.items():
            out[group] = sum(stages[m] for m in members) + launches[group]
        out["total"] = sum(stages.values()) + sum(launches.values())
        return out
