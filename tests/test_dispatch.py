"""A world's heavy loops give the same bits run serially or in parallel (sandbox/dispatch.py), and a
CPU run that takes CUDA's loop shapes gives the stored bits (backend.loop_arch)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from sandbox import Scene, World, backend, dispatch
from sandbox.scene.library import resolve_scene
from tests import state_hashes as sh


def _final_state(scene: str, solver: str, steps: int):
    world = World(Scene.load(resolve_scene(scene)), solver=solver, iterations=8, arch="cpu")
    world.step(steps)
    state = world.state()
    chosen = world._edits.dispatch
    world.close()
    return chosen, state


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_serial_and_parallel_dispatch_end_in_the_same_bits(monkeypatch, solver):
    if backend.loop_arch() != "cpu":
        pytest.skip("the CPU's own loop shapes only (this session takes CUDA's)")
    chosen, serial = _final_state("mixed_on_terrain", solver, 40)
    assert chosen is dispatch.SERIAL  # a small scene on the CPU runs its heavy loops on one thread
    monkeypatch.setattr(dispatch, "SERIAL_BODY_LIMIT", 0)
    chosen, parallel = _final_state("mixed_on_terrain", solver, 40)
    assert chosen is dispatch.PARALLEL
    for key, value in serial.items():
        np.testing.assert_array_equal(value, parallel[key], err_msg=key)


def test_cuda_never_runs_serially():
    assert dispatch.dispatch_for("cuda", 64) is dispatch.PARALLEL
    assert dispatch.dispatch_for("cpu", dispatch.SERIAL_BODY_LIMIT) is dispatch.SERIAL
    assert dispatch.dispatch_for("cpu", 2 * dispatch.SERIAL_BODY_LIMIT) is dispatch.PARALLEL


CUDA_SHAPE_CASES = ("stack_20-mass-splitting-60", "stack_20-block-mass-splitting-60", "stack_20-pgs-colored-60",
                    "playground-mass-splitting-60", "mass_ratio_stacks-mass-splitting-60",
                    "stack_20-mass-splitting-60-4it")
"""Both split schedules, the per-colour launches, the web's default scene (mixed shapes,
sleeping), light bodies' extra sweeps (solvers/light_bodies.py, added 2026-11-27) and two
sweeps of each kind per substep at 4 iterations (Settings.step_sweeps, unrolled; added
2026-11-28). Serial PGS is not here: its sweep is one thread by design, a serial task the
loops-only check below would refuse (tests/test_solvers.py checks its unrolled launch). On
2026-11-26 all 31 quick cases were run this way and matched (docs/bench.md)."""

CHILD = """
import sys
from tests import state_hashes as sh
cases = {c.id: c for c in sh.quick_cases()}
from sandbox import backend, dispatch
from sandbox.solvers import substep
backend.init("cpu")
assert backend.loop_arch() == "cuda" and not backend.serialize_light_loops()
launches = [0]
one_substep = substep.substep_parallel
def counted(*args):
    launches[0] += 1
    return one_substep(*args)
substep.substep_parallel = counted  # the GPU's iteration launch, looked up at each call
from sandbox import Scene
for cid in sys.argv[1:]:
    before = launches[0]
    print(cid, sh.run_case(cases[cid]), flush=True)
    iterations = cases[cid].iterations or Scene.load(cases[cid].path).solver.iterations
    print("launches", cid, launches[0] - before, cases[cid].steps * iterations, flush=True)
import contextlib, io, taichi as ti
table = io.StringIO()
with contextlib.redirect_stdout(table):
    ti.profiler.print_kernel_profiler_info("count")
names = sorted({w for line in table.getvalue().splitlines() for w in line.split() if w.startswith("substep_parallel")})
print("substep tasks", *names)
"""


def test_cuda_loop_shapes_on_the_cpu_give_the_stored_bits():
    """Every loop parallel on Taichi's worker threads, the iteration loop one launch per substep,
    as on a GPU: a loop whose result hung on its order (a race the CPU's serial light loops
    hide) would change the bits. A fresh process, since the shapes are fixed at compile time;
    Taichi's kernel profiler there lists the substep launch's tasks (solvers/substep_loops.py)."""
    stored = sh.stored()
    if stored is None:
        pytest.skip(sh.no_platform_message())
    paths = [str(sh.ROOT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]  # and any site given
    env = {**os.environ, "SANDBOX_LOOPS": "cuda", "PYTHONPATH": os.pathsep.join(paths), "TI_KERNEL_PROFILER": "1"}
    run = subprocess.run([sys.executable, "-c", CHILD, *CUDA_SHAPE_CASES], capture_output=True, text=True,
                         env=env, cwd=sh.ROOT, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    results = dict(line.split(" ", 1) for line in run.stdout.splitlines() if line.startswith(CUDA_SHAPE_CASES))
    for cid in CUDA_SHAPE_CASES:
        assert sh.is_hash(stored.get(cid, "")), f"{cid}: no stored hash to compare with"
        assert results.get(cid) == stored[cid], f"{cid} under SANDBOX_LOOPS=cuda: {results.get(cid)}"
    # the shapes were taken: the split schedules' worlds launch once per substep (steps x
    # iterations), where a CPU world of their size runs its whole iteration loop in one launch
    counts = {cid: (int(n), int(substeps)) for _, cid, n, substeps in
              (line.split() for line in run.stdout.splitlines() if line.startswith("launches "))}
    for cid in ("stack_20-mass-splitting-60", "stack_20-block-mass-splitting-60", "stack_20-mass-splitting-60-4it"):
        launched, substeps = counts[cid]
        assert launched == substeps, f"{cid}: {launched} substep launches for {substeps} substeps"
    # and each launch is its loops alone: a statement between two loops (a range read at run
    # time, a value argument's copy) would be a single-thread task, on a GPU a launch of its own
    tasks = next(line.split()[2:] for line in run.stdout.splitlines() if line.startswith("substep tasks"))
    assert tasks and not [t for t in tasks if not t.endswith("_range_for")], tasks


def test_an_unknown_loop_shape_is_refused(monkeypatch):
    from sandbox import SandboxError

    monkeypatch.setenv(backend.LOOPS_ENV, "gpu")
    with pytest.raises(SandboxError, match="SANDBOX_LOOPS"):
        backend._loops_asked("cpu")
