"""Which values each setting takes, and the one check that refuses the others.

A setting outside its domain is refused when the ``Settings`` is made, with the library's error
naming the setting, what it takes and what it got: a NaN spring, 0 sweeps or a warm start of 2
would otherwise reach the kernels as given. Scene files are checked by the scene reader with their
file and entry; this is the check of the Python API (and of what the reader hands on).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SandboxError

ITERATION_LAUNCHES = ("auto", "shared", "one", "per-substep", "per-stage")
FORMULATIONS = ("soft-step", "paper")
MAX_RATIO_SWEEPS = 8
"""The most ``ratio_sweeps`` a world takes: a GPU's per-substep launch unrolls them."""
MAX_STEP_SWEEPS = 16
"""The most ``step_sweeps`` a world takes: a GPU's per-substep launch unrolls a substep's
sweeps of each kind (all of them at 1 iteration)."""


def _is_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float))


@dataclass(frozen=True)
class Choice:
    """One of ``options``."""

    options: tuple

    def accepts(self, value) -> bool:
        return value in self.options

    def refusal(self, name: str, value) -> str:
        return f"unknown {name} {value!r}; choose one of {', '.join(self.options)}"


@dataclass(frozen=True)
class Number:
    """Above ``low`` (``low`` itself too unless ``open_low``) and below ``below``; finite unless
    ``finite`` is False (then inf is a value with a meaning, given in ``note``)."""

    low: float = 0.0
    open_low: bool = False
    below: float = math.inf
    finite: bool = True
    note: str = ""

    def accepts(self, value) -> bool:
        if not _is_number(value) or (self.finite and not math.isfinite(value)):
            return False
        return (value > self.low if self.open_low else value >= self.low) and (self.below == math.inf
                                                                              or value < self.below)

    def refusal(self, name: str, value) -> str:
        span = f"{'>' if self.open_low else '>='} {self.low:g}" + (
            f" and < {self.below:g}" if self.below != math.inf else "")
        kind = "a finite number" if self.finite else "a number"
        return f"{name} must be {kind} {span}{self.note}, got {value!r}"


@dataclass(frozen=True)
class Within:
    """In the closed interval [``low``, ``high``]."""

    low: float
    high: float
    label: str = "a number "
    note: str = ""

    def accepts(self, value) -> bool:
        return _is_number(value) and math.isfinite(value) and self.low <= value <= self.high

    def refusal(self, name: str, value) -> str:
        return f"{name} must be {self.label}in [{self.low:.5g}, {self.high:.5g}]{self.note}, got {value!r}"


@dataclass(frozen=True)
class Whole:
    """A whole number from ``low``, up to ``high`` where one is given."""

    low: int
    high: int | None = None

    def accepts(self, value) -> bool:
        return (not isinstance(value, bool) and isinstance(value, int) and value >= self.low
                and (self.high is None or value <= self.high))

    def refusal(self, name: str, value) -> str:
        span = f"in [{self.low}, {self.high}]" if self.high is not None else f">= {self.low}"
        return f"{name} must be a whole number {span}, got {value!r}"


@dataclass(frozen=True)
class Flag:
    """True or False."""

    def accepts(self, value) -> bool:
        return isinstance(value, bool)

    def refusal(self, name: str, value) -> str:
        return f"{name} must be true or false, got {value!r}"


REUSE_OFF = " (0 turns manifold reuse off)"
SHARE = Within(0.0, 1.0)

DOMAINS = {
    "iteration_launch": Choice(ITERATION_LAUNCHES),
    "formulation": Choice(FORMULATIONS),
    "sleep_linear_speed": Number(),
    "sleep_angular_speed": Number(),
    "sleep_time": Number(),
    "speculative_speed": Number(),
    "manifold_reuse_distance": Number(note=REUSE_OFF),
    "manifold_reuse_angle": Within(0.0, math.pi, label="", note=REUSE_OFF),
    "pair_reuse_margin": Number(),
    "contact_margin": Number(),
    "slop": Number(),
    "contact_hertz": Number(open_low=True),
    "match_distance": Number(),
    "jacobi_relaxation": Number(open_low=True),
    "fracture_min_piece_size": Number(open_low=True),
    "contact_stiffness_limit": Number(),
    "contact_damping_ratio": Number(),
    "light_damping_ratio": Number(),
    "contact_rocking_stiffness": Number(),
    "contact_deflection": Number(),
    "contact_load_time": Number(open_low=True),
    "contact_preload_lag": Number(open_low=True),
    "split_relaxation": Number(open_low=True, below=2.0),
    "relax_push_speed": Number(),
    "overlap_push_speed": Number(open_low=True),
    "baumgarte": Number(below=1.0),
    "idle_split": Number(open_low=True, below=1.0),
    "restitution_tolerance": Number(open_low=True),
    "restitution_threshold": Number(open_low=True),
    "ratio_mass": Number(low=1.0, open_low=True),
    "ratio_sweeps": Whole(0, MAX_RATIO_SWEEPS),
    "step_sweeps": Whole(0, MAX_STEP_SWEEPS),
    "contact_preload": SHARE,
    "warm_start": SHARE,
    "max_push_speed": Number(open_low=True, finite=False, note=" (inf: no cap)"),
    "sweeps": Whole(1),
    "max_bodies": Whole(1),
    "speculative_contacts": Flag(),
}
"""Every setting's domain, checked in this order (the first setting out of its domain is named)."""


def check_settings(settings) -> None:
    """Raise SandboxError for the first setting of ``settings`` outside its domain."""
    for name, domain in DOMAINS.items():
        value = getattr(settings, name)
        if not domain.accepts(value):
            raise SandboxError(domain.refusal(name, value))
