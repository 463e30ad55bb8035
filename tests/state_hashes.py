"""Bitwise state hashes of the shipped scenes (issue 19): a change meant to leave the physics
alone (a refactor, a faster kernel) must leave every hash alone, which no tolerance-based test
can prove.

A hash is the sha256 of the float32 bytes of ``World.state()`` after a fixed number of steps.
The bits depend on the Taichi version and on the CPU and compiler, so the stored hashes
(``tests/data/state_hashes.json``, ``{platform_key: {case_id: hash}}``) are kept per
``platform_key()``; a platform without an entry is not checked.

Cases (``Case.id`` is ``scene-solver-steps``, ``-<k>it`` added where the case sets the iteration
count), every one on the CPU with the scene's own iteration count and solver options
(pgs-colored: its defaults) unless it sets the count:

- QUICK (``quick_cases()``): every shipped scene with its own solver, 60 steps (tests/test_scenes_smoke.py
  checks these on the world it already steps); ``stack_20``, ``friction_arch`` and
  ``mass_ratio_stacks`` with each solver, 60 steps (tests/test_state_hashes.py); and
  FEW_ITERATIONS, below 8 iterations (several sweeps of each kind per substep,
  Settings.step_sweeps: the scenes all ask for 10 or more);
- FULL (``full_cases()``, ``pytest --stress``): every scene with every solver, 120 steps (all
  of them: generating QUICK and FULL took 8.5 min on the 2-core VM).

A case whose world cannot be built, or whose world fails a step (a SandboxError either way: the
solver cannot run the scene, or diverges), stores the error's text instead of a hash; the text
is checked like a hash (a solver that diverges elsewhere has changed too); none does today.
Regenerate the current platform's hashes (other platforms' entries are kept) with

    PYTHONPATH=$PWD python -m tests.state_hashes [quick|full] [CASE_ID ...]

``quick`` runs QUICK, ``full`` QUICK and FULL; case ids restrict the run to those cases.
Each case prints its time and whether its hash is new, the same or changed, so a second run
shows whether the runs are repeatable.
"""

from __future__ import annotations

import hashlib
import json
import platform
import sys
import time
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE_DIR = ROOT / "scenes"
DATA = Path(__file__).resolve().parent / "data" / "state_hashes.json"
STATE_KEYS = ("position", "orientation", "linear_velocity", "angular_velocity")
SOLVER_NAMES = ("pgs", "pgs-colored", "jacobi", "mass-splitting", "block-mass-splitting")
"""``sandbox.solvers.SOLVERS``' keys, spelled out so that collecting the cases imports no Taichi
(tests/test_state_hashes.py checks that the two agree)."""
EVERY_SOLVER_SCENES = ("stack_20", "friction_arch", "mass_ratio_stacks")
"""QUICK's scenes run with every solver: contact-heavy ones where the solvers differ most."""
QUICK_STEPS, FULL_STEPS = 60, 120
FEW_ITERATIONS = (("stack_20", "mass-splitting", 4), ("friction_arch", "block-mass-splitting", 4),
                  ("stack_20", "jacobi", 2), ("friction_arch", "pgs", 2))
"""(scene, solver, iterations) of QUICK's cases below the scenes' own counts."""


@dataclass(frozen=True)
class Case:
    scene: str  # stem of scenes/<scene>.toml
    solver: str
    steps: int
    own: bool  # the scene's own solver
    iterations: int | None = None  # None: the scene's own

    @property
    def id(self) -> str:
        return f"{self.scene}-{self.solver}-{self.steps}" + (f"-{self.iterations}it" if self.iterations else "")

    @property
    def path(self) -> Path:
        return SCENE_DIR / f"{self.scene}.toml"


def scene_paths() -> list[Path]:
    return sorted(SCENE_DIR.glob("*.toml"))


def own_solver(path: Path) -> str:
    """The scene's ``[solver] name``, read from the TOML (Scene.load would decompose meshes)."""
    with open(path, "rb") as f:
        return tomllib.load(f).get("solver", {}).get("name", "pgs")


def own_case(path: Path, steps: int = QUICK_STEPS) -> Case:
    return Case(path.stem, own_solver(path), steps, own=True)


def _unique(cases) -> list[Case]:
    """First of each id: a scene's own-solver case also appears in its every-solver list."""
    seen: dict[str, Case] = {}
    for c in cases:
        seen.setdefault(c.id, c)
    return list(seen.values())


def quick_cases() -> list[Case]:
    own = [own_case(p) for p in scene_paths()]
    solvers = {c.scene: c.solver for c in own}
    every = [Case(s, name, QUICK_STEPS, own=name == solvers[s]) for s in EVERY_SOLVER_SCENES for name in SOLVER_NAMES]
    few = [Case(s, name, QUICK_STEPS, own=False, iterations=k) for s, name, k in FEW_ITERATIONS]
    return _unique(own + every + few)


def full_cases() -> list[Case]:
    return [Case(p.stem, name, FULL_STEPS, own=name == own_solver(p)) for p in scene_paths() for name in SOLVER_NAMES]


def hash_state(state: dict) -> str:
    """sha256 of the float32 bytes of a ``World.state()`` dict, in STATE_KEYS order."""
    h = hashlib.sha256()
    for key in STATE_KEYS:
        h.update(state[key].astype("<f4", copy=False).tobytes(order="C"))
    return h.hexdigest()


def state_hash(world) -> str:
    return hash_state(world.state())


def cpu_model() -> str:
    """The CPU's model name with its family and model numbers: a virtual machine may name only
    the vendor line ("AMD EPYC"), while Taichi's JIT compiles for the instruction sets of the
    generation underneath (AVX-512 or not), which can change the bits."""
    fields = {}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            fields.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    name = fields.get("model name") or platform.processor() or "unknown CPU"
    if "cpu family" in fields and "model" in fields:
        name += f" (family {fields['cpu family']}, model {fields['model']})"
    return name


def platform_key() -> str:
    """What the bits depend on besides the code: Taichi (its LLVM), the machine, the CPU model."""
    import taichi as ti

    return f"taichi {'.'.join(map(str, ti.__version__))} {platform.machine()} {cpu_model()}"


def run_case(case: Case) -> str:
    """The case's hash, or ``"<error class>: <message>"`` when building or stepping its world
    raises a SandboxError."""
    from sandbox import SandboxError, Scene, World

    scene = Scene.load(case.path)
    try:
        world = World(scene, solver=case.solver, iterations=case.iterations, arch="cpu")
    except SandboxError as exc:
        return f"{type(exc).__name__}: {exc}"
    try:
        world.step(case.steps)
        return state_hash(world)
    except SandboxError as exc:
        return f"{type(exc).__name__}: {exc}"
    finally:
        world.close()


def comparable() -> bool:
    """Whether this process can check the stored bits: they are the CPU's (a CUDA session, whose
    atomics commit in any order, skips them; ``SANDBOX_LOOPS=cuda`` on the CPU keeps them)."""
    from sandbox import backend

    return backend.active_arch() in (None, "cpu")


def is_hash(result: str) -> bool:
    return len(result) == 64 and all(ch in "0123456789abcdef" for ch in result)


def load_all() -> dict:
    return json.loads(DATA.read_text()) if DATA.exists() else {}


@lru_cache(maxsize=1)
def stored() -> dict | None:
    """This platform's stored hashes, or None when it has none."""
    return load_all().get(platform_key())


def regenerate_hint(case: Case) -> str:
    mode = "quick" if case.steps == QUICK_STEPS else "full"
    return f"PYTHONPATH=$PWD python -m tests.state_hashes {mode}"


def no_platform_message() -> str:
    return (f"no state hashes stored for this platform ({platform_key()!r}) in {DATA.relative_to(ROOT)}; "
            f"generate them with `PYTHONPATH=$PWD python -m tests.state_hashes quick` (or `full` for --stress)")


def mismatch(case: Case, expected: str | None, actual: str) -> str | None:
    """The failure message for a case whose result is not the stored one, else None."""
    if expected == actual:
        return None
    if expected is None:
        return (f"{case.id}: no stored hash for this case on {platform_key()!r}; "
                f"generate it with `{regenerate_hint(case)} {case.id}` and commit {DATA.relative_to(ROOT)}")
    return (f"{case.id}: the state after {case.steps} steps ({case.solver}) is no longer bit-for-bit the stored "
            f"one: the physics changed (stored {expected}, now {actual}). If the change is intended, regenerate "
            f"with `PYTHONPATH=$PWD python -m tests.state_hashes full` (`quick` leaves the --stress hashes as they "
            f"were) and commit {DATA.relative_to(ROOT)}")


def main(argv: list[str]) -> int:
    mode = argv[0] if argv else "quick"
    if mode not in ("quick", "full"):
        print(__doc__)
        return 2
    known = {c.id: c for c in _unique(quick_cases() + full_cases())}
    cases = _unique(quick_cases() + (full_cases() if mode == "full" else []))
    if argv[1:]:
        unknown = [i for i in argv[1:] if i not in known]
        if unknown:
            print(f"unknown case id(s): {', '.join(unknown)}")
            return 2
        cases = [known[i] for i in argv[1:]]
    data = load_all()
    key = platform_key()
    entry = {k: v for k, v in data.get(key, {}).items() if k in known}  # drop cases that no longer exist
    print(f"platform {key!r}: {len(cases)} cases")
    start = time.perf_counter()
    for c in cases:
        t0 = time.perf_counter()
        result = run_case(c)
        old = entry.get(c.id)
        status = "new" if old is None else ("same" if old == result else "CHANGED")
        entry[c.id] = result
        shown = result[:16] if is_hash(result) else result
        print(f"{time.perf_counter() - t0:7.1f} s  {c.id:40s} {status:8s} {shown}", flush=True)
        data[key] = dict(sorted(entry.items()))
        DATA.parent.mkdir(parents=True, exist_ok=True)
        # written after each case, so that a long run cut short keeps its work
        DATA.write_text(json.dumps(dict(sorted(data.items())), indent=1) + "\n")
    print(f"{time.perf_counter() - start:7.1f} s  total")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
