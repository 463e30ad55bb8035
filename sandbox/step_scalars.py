"""The fused step kernels' scalar arguments, kept on the device and written when they change.

A launch costs Taichi ~3 us of Python per scalar argument (type checks, then setting it in the
launch context), and the two launches of a small world's step took 16 of them, all fixed while
the settings, the solver, dt and the iteration count are: a tenth of a 20-box step. The fused
kernels of ``step_kernels.py`` read them from ``StepScalars`` instead; the per-stage kernels
(the profiled path) keep their arguments. The values are the arguments' float32 / int32
conversions, so the kernels see the same numbers.
"""

from __future__ import annotations

import taichi as ti

from .manifold_cache import overlap_depth

(MARGIN, SLOP, STEP, REUSE_D2, REUSE_SIN, MATCH_DISTANCE, WARM_FACTOR, RELAXATION, SUBSTEP, SLEEP_LINEAR,
 SLEEP_ANGULAR, SLEEP_TIME, OVERLAP_DEPTH, PAIR_REUSE_MARGIN) = range(14)
"""Indices of ``StepScalars.f``: contact margin and slop [m], the step [s], the manifold-reuse
bounds (Settings.manifold_reuse_bounds), the warm-start match distance [m] and factor, the
schedule's relaxation, the substep [s], the sleep thresholds [m/s, rad/s] and time [s], and the
depth beyond the slop that marks a new pair overlapping [fraction of its bound]
(manifold_cache.overlap_depth), and the broadphase's pair-reuse growth [m]
(Settings.pair_reuse_margin)."""
FLOAT_COUNT = 14

SUBSTEPS, BIASED_SWEEPS, RELAX_SWEEPS = range(3)
"""Indices of ``StepScalars.i``: formulation.SweepPlan's counts."""
INT_COUNT = 3


@ti.data_oriented
class StepScalars:
    def __init__(self):
        self.f = ti.field(ti.f32, FLOAT_COUNT)
        self.i = ti.field(ti.i32, INT_COUNT)


def step_scalar_values(settings, relaxation: float, h: float, plan) -> tuple[tuple, tuple]:
    """(floats, ints) of a step of ``h`` [s] with ``plan`` (formulation.SweepPlan) under
    ``settings``, for a schedule whose merge uses ``relaxation`` (Schedule.relaxation)."""
    reuse_d2, reuse_sin = settings.manifold_reuse_bounds()
    floats = [0.0] * FLOAT_COUNT
    floats[MARGIN] = settings.contact_margin
    floats[SLOP] = settings.slop
    floats[STEP] = h
    floats[REUSE_D2], floats[REUSE_SIN] = reuse_d2, reuse_sin
    floats[MATCH_DISTANCE] = settings.match_distance
    floats[WARM_FACTOR] = settings.warm_start / plan.substeps
    floats[RELAXATION] = relaxation
    floats[SUBSTEP] = h / plan.substeps
    floats[SLEEP_LINEAR] = settings.sleep_linear_speed
    floats[SLEEP_ANGULAR] = settings.sleep_angular_speed
    floats[SLEEP_TIME] = settings.sleep_time
    floats[OVERLAP_DEPTH] = overlap_depth(settings)
    floats[PAIR_REUSE_MARGIN] = settings.pair_reuse_margin
    ints = [0] * INT_COUNT
    ints[SUBSTEPS], ints[BIASED_SWEEPS], ints[RELAX_SWEEPS] = plan.substeps, plan.biased, plan.relax
    return tuple(float(x) for x in floats), tuple(int(x) for x in ints)
