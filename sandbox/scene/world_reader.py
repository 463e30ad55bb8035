"""Readers of ``[world]`` and ``[solver]`` (and of a ``solver`` event, which shares the latter's schema)."""

from __future__ import annotations

from ..settings import FORMULATIONS
from .keys import MAX_ITERATIONS, MAX_SEED, SOLVER_KEYS, SOLVER_NAMES, SOLVER_OPTION_KEYS, SOLVER_OPTIONS, WORLD_KEYS
from .schema import Reader
from .spec import SolverSpec, WorldSpec


def read_world(r: Reader | None) -> WorldSpec:
    if r is None:
        return WorldSpec()
    r.check_keys(WORLD_KEYS, what="[world]")
    return WorldSpec(
        gravity=r.vector("gravity", 3, (0.0, 0.0, -9.81)),
        dt=r.real("dt", 1.0 / 60.0, positive=True),
        substeps=r.integer("substeps", 1, minimum=1, maximum=10_000),
        contact_hertz=r.real("contact_hertz", None, positive=True),
        duration=r.real("duration", None, positive=True),
        speculative_contacts=r.boolean("speculative_contacts", None),
        speculative_speed=r.real("speculative_speed", None, nonnegative=True),
        formulation=r.string("formulation", None, choices=FORMULATIONS, what="formulation"),
        baumgarte=r.real("baumgarte", None, low=0.0, high=1.0, open_high=True),
    )


def read_solver(r: Reader | None) -> SolverSpec:
    if r is None:
        return SolverSpec()
    r.check_keys(SOLVER_KEYS, what="[solver]")
    name = r.string("name", "pgs", choices=SOLVER_NAMES, what="solver")
    return SolverSpec(
        name=name,
        iterations=r.integer("iterations", 10, minimum=1, maximum=MAX_ITERATIONS),
        options=_read_solver_options(r, name),
    )


def _read_solver_options(r: Reader, name: str) -> dict:
    """The options given for solver ``name`` (only those present: the solver fills in its defaults)."""
    for key in SOLVER_OPTION_KEYS:
        if r.has(key) and key not in SOLVER_OPTIONS[name]:
            takes = ", ".join(SOLVER_OPTIONS[name]) or "no options"
            raise r.error(f"option '{key}' does not apply to solver '{name}' (it takes: {takes})", key)
    options = {}
    if r.has("shuffle"):
        options["shuffle"] = r.boolean("shuffle")
    if r.has("relaxation"):
        options["relaxation"] = r.real("relaxation", low=0.0, high=2.0, open_low=True, open_high=True)
    if r.has("seed"):
        options["seed"] = r.integer("seed", minimum=0, maximum=MAX_SEED)
    return options


def read_solver_change(r: Reader) -> tuple[str, int | None, dict]:
    """A ``solver`` event: the new solver's name, iteration count (None keeps it) and options."""
    name = r.string("name", choices=SOLVER_NAMES, what="solver")
    return name, r.integer("iterations", None, minimum=1, maximum=MAX_ITERATIONS), _read_solver_options(r, name)

