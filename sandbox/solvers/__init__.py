"""Contact solvers chosen by name; all share the contact rows, friction model,
warm starting and position correction (solvers/rows.py), so a comparison
measures the schedule and nothing else.

| name                   | visits                    | combines                               |
|------------------------|---------------------------|----------------------------------------|
| pgs                    | manifolds, serial order   | in place (Gauss-Seidel)                |
| pgs-colored            | colours in sequence       | in place, parallel within a colour     |
| jacobi                 | points, all in parallel   | sum of increments x relaxation         |
| mass-splitting         | points, all in parallel   | split masses, average of sub-bodies    |
| block-mass-splitting   | manifolds, in parallel    | split masses per manifold, average     |
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import SandboxError


@dataclass(frozen=True)
class SolverInfo:
    name: str
    block: str  # "point" or "manifold"
    description: str
    defaults: dict = field(default_factory=dict)


SOLVERS = {
    "pgs": SolverInfo("pgs", "manifold", "serial projected Gauss-Seidel (the deterministic reference)"),
    "pgs-colored": SolverInfo(
        "pgs-colored", "manifold", "parallel PGS over graph colours; shuffle=True permutes order every step",
        {"shuffle": False, "seed": 0},
    ),
    "jacobi": SolverInfo("jacobi", "point", "projected Jacobi with relaxation", {"relaxation": None}),
    "mass-splitting": SolverInfo(
        "mass-splitting", "point", "Tonge et al. 2012, one sub-body per contact point", {"relaxation": None}
    ),
    "block-mass-splitting": SolverInfo(
        "block-mass-splitting", "manifold", "Tonge et al. 2012, one sub-body per contact manifold (block)",
        {"relaxation": None},
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
    if name == "pgs-colored":
        if not isinstance(merged["shuffle"], bool):
            raise SandboxError(f"pgs-colored option shuffle must be true or false, got {merged['shuffle']!r}")
        if isinstance(merged["seed"], bool) or not isinstance(merged["seed"], int):
            raise SandboxError(f"pgs-colored option seed must be an integer, got {merged['seed']!r}")
    return merged
