"""The two time-stepping schemes (sandbox/formulation.py): the paper's one-step Baumgarte
solve does what its equations say, keeps its push-out as momentum where the soft step takes
it back, and a switch between them is a logged, replayable edit."""

import numpy as np
import pytest

from sandbox import Scene, SandboxError, Settings, World
from sandbox.recording import Recorder, replay
from sandbox.scene.library import SCENES_DIR
from tests.helpers import TEST_ARCH

DT = 1.0 / 60.0


def _overlapping_box(depth: float, formulation: str, **settings) -> World:
    """A unit box sunk ``depth`` into the ground, zero gravity, serial PGS converged (50 sweeps)."""
    scene = Scene.from_dict({
        "world": {"dt": DT, "gravity": [0.0, 0.0, 0.0]},
        "solver": {"name": "pgs", "iterations": 50},
        "static": [{"shape": "plane", "normal": [0, 0, 1], "offset": 0.0, "friction": 0.5}],
        "body": [{"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [0.0, 0.0, 0.5 - depth]}],
    })
    return World(scene, arch=TEST_ARCH, settings=Settings(formulation=formulation, **settings))


def test_paper_baumgarte_step_pushes_out_at_gamma_depth_over_dt_and_keeps_the_momentum():
    """Seeds, 'Position projection': the solve asks J v >= (gamma / h) phi beyond the slop, and the
    positions move with that velocity. Nothing takes it back, so the box leaves the ground with it:
    the energy Baumgarte adds (docs/method-notes.md)."""
    depth, gamma = 0.02, 0.8
    world = _overlapping_box(depth, "paper", baumgarte=gamma)
    slop = world.settings.slop
    world.step(1)
    expected = gamma * (depth - slop) / DT  # 0.936 m/s, under the 3 m/s push cap
    vz = float(world.state()["linear_velocity"][0, 2])
    assert vz == pytest.approx(expected, rel=1e-3)
    z1 = float(world.state()["position"][0, 2])
    assert z1 == pytest.approx(0.5 - depth + expected * DT, abs=1e-5)
    world.step(10)
    assert float(world.state()["linear_velocity"][0, 2]) == pytest.approx(expected, rel=1e-3)  # flies off


def test_soft_step_takes_most_of_its_push_out_velocity_back():
    """The same overlap under the soft step: the spring pushes the box out over several substeps
    and each relax sweep takes the push velocity back. One relax sweep per substep leaves a
    residue (measured 0.027 m/s, the four corner rows of serial PGS not quite converged), 35x
    less than the paper's scheme keeps."""
    world = _overlapping_box(0.02, "soft-step")
    peak = 0.0
    for _ in range(60):
        world.step(1)
        peak = max(peak, float(np.abs(world.state()["linear_velocity"][0, 2])))
    assert peak < 0.05  # [m/s] the paper's scheme: 0.94


def test_formulation_comes_from_the_scene_the_constructor_and_the_setter():
    data = {"world": {"formulation": "paper", "baumgarte": 0.5},
            "body": [{"shape": "sphere", "radius": 0.5, "position": [0.0, 0.0, 2.0]}]}
    world = World(Scene.from_dict(data), arch=TEST_ARCH)
    assert (world.formulation, world.settings.baumgarte) == ("paper", 0.5)
    assert World(Scene.from_dict(data), arch=TEST_ARCH, formulation="soft-step").formulation == "soft-step"
    world.set_formulation("soft-step")
    assert world.formulation == "soft-step" and world.settings.baumgarte == 0.5
    with pytest.raises(SandboxError, match="unknown formulation"):
        world.set_formulation("baraff")
    with pytest.raises(SandboxError, match="baumgarte"):
        world.set_formulation("paper", baumgarte=1.5)
    assert world.formulation == "soft-step"  # a refused switch changes nothing


@pytest.mark.parametrize("entry, message", [
    ({"world": {"formulation": "papers"}}, "unknown formulation 'papers'"),
    ({"world": {"baumgarte": -0.1}}, "world.baumgarte"),
    ({"event": [{"time": 0.0, "kind": "formulation"}]}, "formulation"),
    ({"event": [{"time": 0.0, "kind": "formulation", "formulation": "paper", "baumgarte": 2.0}]}, "baumgarte"),
])
def test_bad_formulation_keys_name_the_entry(entry, message):
    with pytest.raises(SandboxError, match=message):
        Scene.from_dict(entry)


def test_a_formulation_switch_is_logged_and_replays_bit_for_bit(tmp_path):
    """A recording begun after the switch still starts from the world's first settings."""
    path = tmp_path / "stack.toml"
    path.write_text("""
[world]
dt = 0.016666666666666666
[solver]
name = "mass-splitting"
iterations = 8
[[static]]
shape = "plane"
normal = [0.0, 0.0, 1.0]
offset = 0.0
[[generate]]
kind = "stack"
count = 3
half_extents = [0.5, 0.5, 0.5]
position = [0.0, 0.0, 0.5]
gap = 0.01
[[event]]
time = 0.25
kind = "formulation"
formulation = "paper"
""", encoding="utf-8")
    world = World(Scene.load(path), arch=TEST_ARCH)
    world.step(20)
    assert world.formulation == "paper" and world.applied_events[0][1].kind == "formulation"
    rec = Recorder(world, path)  # begun under "paper": the replay must start from "soft-step"
    for _ in range(20):
        world.step(1)
        rec.capture()
    out = tmp_path / "stack.sbrec"
    rec.save(out)
    result = replay(out, arch=TEST_ARCH)
    assert result["first_departure"] is None and result["max_difference"] == 0.0


def _paper_pyramid_ke(solver: str, **options) -> float:
    """Mean kinetic energy [J] over the last 60 of 600 frames of pyramid_20 from rest, paper, 15 iterations."""
    world = World(Scene.load(SCENES_DIR / "pyramid_20.toml"), solver=solver, iterations=15, arch=TEST_ARCH,
                  formulation="paper", **options)
    energies = []
    for _ in range(600):
        world.step(1)
        energies.append(world.metrics()["kinetic_energy"])
    return float(np.mean(energies[-60:]))


@pytest.mark.xfail(strict=True, reason=(
    "measured 2026-11-24 (benchmarks/paper_jitter.py, docs/formulation.md): under the paper's scheme at 15 "
    "iterations the 210-box pyramid does not come to rest with any solver: shuffled parallel PGS 7.6e3 J, "
    "mass splitting 4.7e4 J (thrown 20 m; 5.4e3 and 3.0e4 J on 2026-11-27). Warm starting re-applies last "
    "step's impulse, so a solve that converges less than ~45 % of a slow mode per step extrapolates it, "
    "and Baumgarte's 0.8 feeds it"))
def test_paper_scheme_mass_splitting_is_100x_calmer_than_shuffled_parallel_pgs():
    """Issue 18's figure: the seeds' claim under the seeds' own scheme."""
    ratio = _paper_pyramid_ke("pgs-colored", shuffle=True) / _paper_pyramid_ke("mass-splitting")
    assert ratio >= 100, f"shuffled parallel PGS / mass splitting = {ratio:.3g}"
