"""``sandbox bench``: what accuracy costs in time, per scene x solver x iteration count.

    sandbox bench [SCENES...] [--solvers pgs,mass-splitting,...] [--iterations 1,2,4,...]
                  [--arch cpu] [--out DIR] [--quick]

For every scene x solver x iteration count a fresh world is built and run through the
protocol of ``benchmarks/step_bench.py`` extended by the error metrics of method.md
section 3 (see docs/bench.md for how to read the outputs):

1. ``settle`` frames, metrics read after every frame (the kinetic-energy-vs-frame series;
   the first frame also compiles the kernels, reported apart as ``compile_s``);
2. ``window`` more frames, metrics after every frame: the *error* of the row, i.e. the
   mean kinetic energy of what should be at rest (and its std), max and mean penetration,
   RMS and max LCP residual of the rigid (relax) problem the step ends with, and the drift
   of a marker body (the dynamic body highest at t = 0: top of a stack, apex of a pyramid)
   between the end of the settle and the end of the window (M7);
3. ``steps`` steps with per-stage device syncs: ms/step by stage, and ms per solver
   iteration = (integrate_velocities + solve + integrate_positions + relax) / iterations;
4. ``steps`` steps without stage syncs, each step timed between device syncs: mean, median
   and p95 ms/step and steps/s (the number to compare with other engines).

An *iteration* here is a substep of a soft step (Box2D v3): gravity, warm start, one
biased sweep, position update, one relax sweep (docs/method-notes.md), so the iteration
count also sets the substep size. That changes the physics, not just the convergence, so
the convergence of the solver proper is measured apart on a *frozen* problem: each scene is
settled once with serial PGS at the scene's own iteration count, the settled state becomes
a new scene, and one step of it is solved with ``iterations=1``, ``Settings(sweeps=N,
warm_start=0)`` and ``record_residuals``: the RMS residual of the biased problem after
every sweep, for every solver, on identical rows (column ``frozen_residual`` = the residual
after as many sweeps as the row's iteration count).

Scaling: grid piles of growing size (``Scene.from_dict``), ms/step against bodies and
contact points. Peers: when pybullet is importable, every box-and-plane scene also runs in
pybullet (set up by ``sandbox/peers.py``, shared with ``benchmarks/peer_speed.py``) with the same dt
and ``numSolverIterations`` = iterations, through the same protocol, in the same process.

Outputs in ``--out``: ``bench.csv`` and ``bench.json`` (one row per scene x solver x
iteration count, pybullet rows included), ``scaling.csv``, and PNGs: ``pareto_<scene>``
(error vs ms/step), ``jitter_<scene>`` (kinetic energy vs frame), ``convergence_<scene>``
(frozen-problem residual vs sweep and vs solve time) and ``scaling``.

The package: ``protocol`` (one row: the four phases above, the columns), ``experiments`` (the
frozen problem, the scaling piles), ``report`` (derived tables, CSV, JSON, the printed summary),
``plots`` (the PNGs, from the JSON document alone) and ``driver`` (the configurations and
``run``, the loop over everything). Peer engines are ``sandbox/peers.py``.
"""

from ..profile import STAGES
from .driver import FULL, QUICK, command_line, resolve_config, run
from .experiments import convergence, frozen_problem, grid_pile, run_scaling_point
from .plots import write_plots
from .protocol import (COLUMNS, NOT_MEASURED_FOR_PYBULLET, PER_ITERATION_STAGES, REFERENCE_PEER, SCALING_COLUMNS,
                       marker_index, run_peer, run_sandbox)
from .report import cost_fits, machine

__all__ = ["run", "FULL", "QUICK", "COLUMNS", "SCALING_COLUMNS", "NOT_MEASURED_FOR_PYBULLET", "PER_ITERATION_STAGES",
           "REFERENCE_PEER", "STAGES", "resolve_config", "command_line", "run_sandbox", "run_peer", "marker_index",
           "frozen_problem", "convergence", "grid_pile", "run_scaling_point", "cost_fits", "machine", "write_plots"]
