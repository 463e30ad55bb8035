"""Contact solvers chosen by name; all share the contact rows, friction model,
warm starting and position correction (solvers/rows.py), so a comparison
measures the schedule and nothing else.

Each solver is *described* here by data, and ``solvers/schedule.py`` turns a
description into kernel calls: no code outside this package compares solver names.

| name                   | visits                  | block    | combines                              |
|------------------------|-------------------------|----------|---------------------------------------|
| pgs                    | serial, in buffer order | manifold | in place (Gauss-Seidel)               |
| pgs-colored            | colour by colour        | manifold | in place, parallel within a colour    |
| jacobi                 | all blocks at once      | point    | sum of increments x global relaxation |
| mass-splitting         | all blocks at once      | point    | split masses, average of sub-bodies   |
| block-mass-splitting   | all blocks at once      | manifold | split masses per manifold, average    |

This module stays importable without Taichi: the scene loader reads the registry.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import SandboxError
from ..settings import ITERATION_LAUNCHES

MAX_SEED = 2**31 - 1
"""The largest seed a kernel's 32-bit argument holds (the colouring's; CoACD's too)."""

VISITS = ("serial", "colored", "blocks")
"""How a sweep visits the blocks: one after another in buffer order, the colours of a
greedy graph colouring in sequence (each colour in parallel), or all blocks at once from
the same velocities with a deterministic merge (mass_splitting.py)."""

BLOCKS = ("point", "manifold")
"""What one block is: a contact point, or a manifold (every point of one shape pair)."""

COMBINES = ("in-place", "jacobi", "split")
"""How a block's result reaches its bodies: written in place (Gauss-Seidel); the sum of
every block's change times a relaxation (projected Jacobi: one global split factor); the
average of the sub-bodies of a body split by its block count (mass splitting)."""

LAUNCHES = tuple(launch for launch in ITERATION_LAUNCHES if launch != "auto")
"""How the iteration loop can be launched (``Settings.iteration_launch``, solvers/substep.py)."""


@dataclass(frozen=True)
class SolverInfo:
    """One solver as a schedule over the shared contact rows (module docstring)."""

    name: str
    description: str
    visit: str  # one of VISITS
    block: str  # one of BLOCKS
    combine: str  # one of COMBINES
    defaults: dict = field(default_factory=dict)  # its options, with their defaults

    def __post_init__(self):
        for what, value, allowed in (("visit", self.visit, VISITS), ("block", self.block, BLOCKS),
                                     ("combine", self.combine, COMBINES)):
            if value not in allowed:
                raise ValueError(f"solver {self.name!r}: {what} {value!r} is not one of {allowed}")
        if (self.visit == "blocks") == (self.combine == "in-place"):
            raise ValueError(f"solver {self.name!r}: blocks visited all at once need a merge, serial ones none")

    @property
    def scales_masses(self) -> bool:
        """A block sees its bodies' inverse masses and inertias scaled: by the body's block
        count over the relaxation (split), or by 1 / relaxation (Jacobi)."""
        return self.combine != "in-place"

    @property
    def splits_masses(self) -> bool:
        """The scale is each body's own block count (mass splitting), not one global factor."""
        return self.combine == "split"

    @property
    def relaxation_setting(self) -> str | None:
        """The ``Settings`` field that gives the merge's relaxation when the ``relaxation``
        option is not given: ``split_relaxation`` for per-point mass splitting (over-relaxed
        within the convergence proof's 0 < omega < 2: it counts every corner of a face as a
        sub-body, a slack over-relaxation takes back), ``jacobi_relaxation`` for projected
        Jacobi (plain Jacobi overshoots; it is the largest omega, each step bounded by the busiest
        body's split, mass_splitting.py). None, i.e. 1, for block mass splitting (a body's
        manifolds mostly push it different ways: no slack to take back, and an over-relaxed
        friction arch collapsed) and in place (only the warm start uses the merge)."""
        if self.combine == "jacobi":
            return "jacobi_relaxation"
        if self.combine == "split" and self.block == "point":
            return "split_relaxation"
        return None

    @property
    def stiffens_rocking(self) -> bool:
        """Its rows the stability limit caps may resist a face's rocking more stiffly than its
        compression (Settings.contact_rocking_stiffness): every schedule but block mass splitting,
        whose block is a whole manifold solved in place and whose limit counts manifolds, not
        points. With it, measured: the 27-box block rang at 2 iterations (mean KE 0.133 J) and the
        1:100 column tipped at 4 (426 mm), both standing without it."""
        return not (self.combine == "split" and self.block == "manifold")

    @property
    def stiffens_light_rows(self) -> bool:
        """The rows its extra sweeps visit (Settings.ratio_sweeps) take the stability limit of
        those sweeps: the schedules whose block is one point, where a light body's split counts
        its points, not its manifolds, and whose limit is that much lower. Measured on the 1:1000
        column: mass splitting at 8 iterations holds with the sweeps and their limit (late
        penetration 15.9 mm with two sweeps, 5.8 mm with six) and fails with either alone (58-962 mm);
        block mass splitting holds at 15 with the sweeps alone (6.6 mm drift with two) and tips with
        their limit (53.7 mm)."""
        return self.block == "point"

    @property
    def needs_coloring(self) -> bool:
        """The schedule colours the manifolds every step (and reports its colour count)."""
        return self.visit == "colored"

    @property
    def launches(self) -> tuple[str, ...]:
        """The iteration launches this schedule can run: a serial sweep has nothing to share
        between threads, and a colour count known only on the device cannot be unrolled into
        one launch per substep (it launches per colour instead)."""
        cannot = {"serial": ("shared",), "colored": ("per-substep",)}.get(self.visit, ())
        return tuple(launch for launch in LAUNCHES if launch not in cannot)


SOLVERS = {
    "pgs": SolverInfo("pgs", "serial projected Gauss-Seidel (the deterministic reference)",
                      visit="serial", block="manifold", combine="in-place"),
    "pgs-colored": SolverInfo(
        "pgs-colored", "parallel PGS over graph colours; shuffle=True permutes order every step",
        visit="colored", block="manifold", combine="in-place", defaults={"shuffle": False, "seed": 0},
    ),
    "jacobi": SolverInfo("jacobi", "projected Jacobi with relaxation",
                         visit="blocks", block="point", combine="jacobi", defaults={"relaxation": None}),
    "mass-splitting": SolverInfo(
        "mass-splitting", "Tonge et al. 2012, one sub-body per contact point",
        visit="blocks", block="point", combine="split", defaults={"relaxation": None},
    ),
    "block-mass-splitting": SolverInfo(
        "block-mass-splitting", "Tonge et al. 2012, one sub-body per contact manifold (block)",
        visit="blocks", block="manifold", combine="split", defaults={"relaxation": None},
    ),
}


def check_solver(name: str, iterations: int, options: dict) -> dict:
    """Validate a solver choice and return its options with defaults filled in."""
    if name not in SOLVERS:
        raise SandboxError(f"unknown solver {name!r}; choose one of {', '.join(SOLVERS)}")
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise SandboxError(f"iterations must be an integer >= 1, got {iterations!r}")
    info = SOLVERS[name]
    unknown = set(options) - set(info.defaults)
    if unknown:
        allowed = ", ".join(info.defaults) or "none"
        raise SandboxError(f"solver {name!r} has no option(s) {', '.join(sorted(unknown))}; allowed: {allowed}")
    merged = dict(info.defaults)
    merged.update(options)
    if merged.get("relaxation") is not None:
        r = merged["relaxation"]
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not (0.0 < float(r) < 2.0):
            raise SandboxError(f"{name} relaxation must be in (0, 2), got {r!r}")
    if "shuffle" in merged and not isinstance(merged["shuffle"], bool):
        raise SandboxError(f"{name} option shuffle must be true or false, got {merged['shuffle']!r}")
    if "seed" in merged and (isinstance(merged["seed"], bool) or not isinstance(merged["seed"], int)
                             or not 0 <= merged["seed"] <= MAX_SEED):
        raise SandboxError(f"{name} option seed must be an integer in [0, {MAX_SEED}], got {merged['seed']!r}")
    return merged
