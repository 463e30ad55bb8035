"""What many test files build or check, written once: scene dicts (boxes, spheres, a ground
plane), the states of two worlds compared bit for bit, and a world stepped while its metrics
are collected. Import with ``from tests.helpers import ...`` (any test folder).

Fixtures stay in ``conftest.py``; this module holds plain functions, so a test reads
where its scene comes from.
"""

from __future__ import annotations

import gzip
import importlib.util
import json
import os
from pathlib import Path

import numpy as np
import pytest

TEST_ARCH = os.environ.get("SANDBOX_TEST_ARCH", "cpu")
"""The Taichi backend of this test run (``SANDBOX_TEST_ARCH=cuda pytest ...`` on a GPU machine):
the session fixture starts it and every test world runs on it. Bitwise repeatability is
promised on the CPU only, so the state-hash checks and the CPU dispatch test skip on another
backend."""
G = 9.81
"""[m/s^2] the magnitude of ``scene_dict``'s default gravity."""
DT = 1.0 / 60.0
"""[s] ``scene_dict``'s default step."""


ANCHOR_SCENES = Path(__file__).resolve().parent / "data" / "anchor_scenes.json.gz"
"""The anchors' scenes (../shared/anchors/scenes.json: numpy default_rng, seed 20120801), cut to the
scenes and fields tests/scene compares with: stack20, pyramid20, pile1000 and
massratio1000_heavy_on_light whole, heightfield_pile's body positions and terrain vertices and
faces. Kept in the repository so the comparisons run wherever the suite does, CI's clean clone
included, instead of skipping where the shared folder is absent."""


def load_benchmark(name: str):
    """The script ``benchmarks/<name>.py`` as a module (benchmarks/ is not a package), for the tests
    that keep a model's findings true."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def anchor_scene(name: str) -> dict:
    """One scene of ``ANCHOR_SCENES``."""
    with gzip.open(ANCHOR_SCENES, "rt") as f:
        return json.load(f)["scenes"][name]


def box_body(position, half=(0.5, 0.5, 0.5), mass=None, density=1000.0, **extra) -> dict:
    """A box entry of a scene dict (the default: a unit cube of 1000 kg)."""
    body = {"shape": "box", "half_extents": list(half), "position": list(position), **extra}
    if mass is not None:
        body["mass"] = mass
    else:
        body["density"] = density
    return body


def sphere_body(position, radius=0.5, density=1000.0, **extra) -> dict:
    return {"shape": "sphere", "radius": radius, "position": list(position), "density": density, **extra}


def plane(normal=(0.0, 0.0, 1.0), offset=0.0, friction=0.5) -> dict:
    return {"shape": "plane", "normal": list(normal), "offset": offset, "friction": friction}


def scene_dict(bodies, statics=(plane(),), gravity=(0.0, 0.0, -G), dt=DT, solver="pgs", iterations=10) -> dict:
    """A scene as ``Scene.from_dict`` reads it: ``bodies`` over ``statics`` (a ground plane)."""
    return {
        "world": {"gravity": list(gravity), "dt": dt, "substeps": 1},
        "solver": {"name": solver, "iterations": iterations},
        "static": list(statics),
        "body": list(bodies),
    }


def assert_same_state(expected: dict, actual: dict, label: str = "") -> None:
    """Two ``World.state()`` dicts hold the same bits (NaN equal to NaN), field by field."""
    assert expected.keys() == actual.keys(), label
    for key in expected:
        np.testing.assert_array_equal(expected[key], actual[key], err_msg=f"{label} {key}".strip())


def assert_same_metrics(expected: dict, actual: dict) -> None:
    """Two ``World.metrics()`` dicts of worlds in the same state agree: bit for bit on the CPU
    (metrics.py sums in index order there); on another backend the counts exactly and the float
    sums to float32 rounding (a GPU sums with float atomics, committed in any order: the
    residual's last bits differed on an H200, 2026-11-27, with the states equal)."""
    assert expected.keys() == actual.keys()
    if TEST_ARCH == "cpu":
        assert expected == actual
        return
    for key, value in expected.items():
        if isinstance(value, float):
            assert actual[key] == pytest.approx(value, rel=1e-5, abs=1e-12), key
        else:
            assert actual[key] == value, key


def run_collecting(world, steps: int, keys=("kinetic_energy", "max_penetration")) -> dict[str, np.ndarray]:
    """Step ``world`` one step at a time, ``steps`` times, and return each metric of ``keys``
    after every step (shape (steps,))."""
    out = {k: np.empty(steps) for k in keys}
    for s in range(steps):
        world.step(1)
        m = world.metrics()
        for k in keys:
            out[k][s] = m[k]
    return out


def compiled_kernel_count() -> int:
    """Kernel instances this process has compiled (or loaded from Taichi's cache) so far: a click
    in the web sandbox that raises it pauses the running world."""
    import gc

    from taichi.lang.kernel_impl import Kernel

    return sum(len(k.compiled_kernels) for k in gc.get_objects() if isinstance(k, Kernel))
