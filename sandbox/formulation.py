"""What one solver iteration means: a soft substep (Box2D v3) or a sweep of the paper's solve.

The two time-stepping schemes a student can compare (``Settings.formulation``):

* ``"soft-step"`` (the default): ``iterations`` substeps of dt / iterations, each with
  gravity, warm start, one biased sweep against soft contact springs, the position update
  and one rigid relax sweep (solvers/rows.py). Position error is removed by the springs,
  whose push-out velocity the relax sweep takes back before it becomes momentum.
* ``"paper"``: the scheme of Tonge et al. 2012 (and of the talk's slides): ONE step of dt,
  gravity, warm start, then ``iterations`` sweeps of one velocity-level LCP with
  accumulated impulse clamping, rigid rows whose target removes ``baumgarte`` of the
  penetration beyond the slop per step (Baumgarte stabilisation), and the positions
  integrated with those biased velocities. No relax sweep: the push-out stays in the
  bodies as momentum, which is how a resting stack under this scheme keeps moving, and how
  an order-dependent sweep (parallel PGS with a shuffled order) turns into visible jitter.

Both run on the same kernels: the paper's solve is a soft-step loop of one substep with
``iterations`` biased sweeps and no relax sweep, whose rows have no compliance and a bias
rate of ``baumgarte / dt`` (contact_spring.row_params, rows.respond_row).
"""

from __future__ import annotations

from dataclasses import dataclass

SOFT_STEP, PAPER = "soft-step", "paper"


@dataclass(frozen=True)
class SweepPlan:
    """How one step's iteration loop runs: ``substeps`` of dt / substeps, each with
    ``biased`` biased sweeps (``Settings.sweeps``, or more at few iterations:
    Settings.step_sweeps, which adds as many relax sweeps), up to ``ratio`` more over
    the rows of bodies resting against far heavier ones (Settings.ratio_sweeps: a step without such
    a pair runs none), the position update, then ``relax`` relax sweeps."""

    substeps: int
    biased: int
    relax: int
    ratio: int = 0


def sweep_plan(formulation: str, iterations: int, sweeps: int, ratio_sweeps: int = 0,
               step_sweeps: int = 0) -> SweepPlan:
    """The plan of a step with ``iterations`` solver iterations, ``Settings.sweeps``,
    ``Settings.step_sweeps`` (the fewest sweeps of each kind of a step, so a step of fewer
    iterations sweeps more than once per substep) and, for a schedule that takes them (the Jacobi
    family), ``Settings.ratio_sweeps``. Under the paper formulation none of them: its solve is the
    paper's."""
    if formulation == PAPER:
        return SweepPlan(substeps=1, biased=iterations * sweeps, relax=0)
    each = max(sweeps, -(-step_sweeps // iterations))  # ceil(step_sweeps / iterations)
    return SweepPlan(substeps=iterations, biased=each, relax=each, ratio=ratio_sweeps)


def baumgarte_rate(settings, dt: float) -> float:
    """[1/s] The paper's bias rate (target velocity per metre of penetration), 0 under the
    soft step (whose rows take their rate from their spring)."""
    if settings.formulation != PAPER:
        return 0.0
    return settings.baumgarte / dt
