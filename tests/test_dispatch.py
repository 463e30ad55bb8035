"""A world's heavy loops give the same bits run serially or in parallel (sandbox/dispatch.py)."""

import numpy as np
import pytest

from sandbox import Scene, World, dispatch
from sandbox.scene.library import resolve_scene


def _final_state(scene: str, solver: str, steps: int):
    world = World(Scene.load(resolve_scene(scene)), solver=solver, iterations=8, arch="cpu")
    world.step(steps)
    state = world.state()
    chosen = world._edits.dispatch
    world.close()
    return chosen, state


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_serial_and_parallel_dispatch_end_in_the_same_bits(monkeypatch, solver):
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
