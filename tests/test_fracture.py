"""Fracture (issue #8): pieces carry the parent's mass and momentum, do not overlap, and the
world swaps them in live; non-convex bodies rest on a plane; breakable bodies break on impact.

The host tests check ``fracture.fracture_body`` in float64. The world tests share one scene
(and so one buffer class: Taichi compiles the kernels once for the whole module) whose state
is float32, which bounds what they can check to float32 rounding.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sandbox.errors import CapacityError, SandboxError
from sandbox.fracture import FractureError, fracture_body
from sandbox.polytope import penetration_depth
from sandbox.scene import EventSpec, load_scene, scene_from_dict
from sandbox.scene.rotations import quat_to_matrix
from sandbox.settings import Settings
from tests.helpers import TEST_ARCH

HOST_RTOL = 1e-9
"""[1] Momentum and mass after a fracture in float64: exact up to the rounding of a few hundred
operations (measured ~1e-16)."""
WORLD_RTOL = 1e-6
"""[1] The issue's bound for momentum at the moment of fracture; the world stores state, masses and
inertia in float32 (relative rounding 6e-8 per value), so this is what a device round trip allows."""
TOUCH = 1e-9
"""[m] Voronoi cells share faces: their overlap is float64 rounding, not penetration. (CoACD's hulls
touch along its cutting planes to ~1e-8 m; decompose.py leaves overlaps below OVERLAP_TOLERANCE times
the mesh's extent, and cuts apart anything deeper.)"""

MOVING = {"linear_velocity": [1.0, -2.0, 0.5], "angular_velocity": [0.7, 0.3, -1.1],
          "orientation": [0.9, 0.2, -0.3, 0.25]}
TORUS = {"kind": "torus", "major_radius": 0.5, "minor_radius": 0.15, "sections": [16, 8]}
BODIES = {
    "box": {"shape": "box", "half_extents": [0.5, 0.3, 0.2]},
    "hull": {"shape": "hull", "vertices": [[0, 0, 0], [1, 0, 0], [0, 0.8, 0], [0.1, 0.2, 0.9], [0.6, 0.6, 0.4]]},
    "sphere": {"shape": "sphere", "radius": 0.4},
    "capsule": {"shape": "capsule", "radius": 0.2, "half_height": 0.5},
    "dumbbell": {"shape": "compound", "parts": [
        {"shape": "capsule", "radius": 0.05, "half_height": 0.5},
        {"shape": "sphere", "radius": 0.2, "position": [0, 0, 0.6]},
        {"shape": "box", "half_extents": [0.15, 0.15, 0.15], "position": [0, 0, -0.6], "density": 7800.0}]},
    "torus": {"shape": "mesh", "generator": TORUS, "decomposition": {"threshold": 0.2}},
}
EXACT = {"box", "hull", "dumbbell", "torus"}
"""Bodies whose pieces partition them exactly (spheres and capsules are cut from a polytope)."""


def _body(kind: str, **extra):
    entry = dict(BODIES[kind], position=[0.3, -0.2, 1.5], **MOVING)
    entry.update(extra)
    (body,) = scene_from_dict({"body": [entry]}, source="fracture.toml").bodies
    return body


def _momentum(bodies) -> tuple[np.ndarray, np.ndarray, float]:
    """Linear momentum, angular momentum about the origin (orbital + spin) and mass, float64."""
    p, l, m = np.zeros(3), np.zeros(3), 0.0
    for b in bodies:
        rot = quat_to_matrix(b.orientation)
        p += b.mass * b.linear_velocity
        l += np.cross(b.position, b.mass * b.linear_velocity) + rot @ b.inertia @ rot.T @ b.angular_velocity
        m += b.mass
    return p, l, m


def _world_vertices(body) -> list[np.ndarray]:
    rot = quat_to_matrix(body.orientation)
    out = []
    for s in body.shapes:
        local = quat_to_matrix(s.local_orientation)
        out.append((np.asarray(s.vertices) @ local.T + s.local_position) @ rot.T + body.position)
    return out


# ---------------------------------------------------------------------------- host: pieces
@pytest.mark.parametrize("impulse", [0.0, 250.0])
@pytest.mark.parametrize("kind", list(BODIES))
def test_fracture_conserves_mass_and_momentum(kind, impulse, coacd_cache):
    parent = _body(kind)
    result = fracture_body(parent, pieces=8, seed=3, impulse=impulse)
    pieces = result.bodies
    assert len(pieces) == (len(parent.shapes) if len(parent.shapes) > 1 else 8)
    p0, l0, m0 = _momentum([parent])
    p1, l1, m1 = _momentum(pieces)
    assert abs(m1 - m0) <= HOST_RTOL * m0  # the issue asks for 1 %; the masses partition the parent
    assert np.linalg.norm(p1 - p0) <= HOST_RTOL * np.linalg.norm(p0)
    assert np.linalg.norm(l1 - l0) <= HOST_RTOL * np.linalg.norm(l0)
    assert result.exact == (kind in EXACT)
    for piece in pieces:
        assert piece.mass > 0 and np.all(np.linalg.eigvalsh(piece.inertia) > 0) and not piece.breakable


@pytest.mark.parametrize("kind", sorted(EXACT))
def test_exact_pieces_keep_the_parent_velocity_field(kind, coacd_cache):
    parent = _body(kind)
    result = fracture_body(parent, pieces=6, seed=1)
    v, w = parent.linear_velocity, parent.angular_velocity
    for piece in result.bodies:
        rigid = v + np.cross(w, piece.position - parent.position)
        assert np.allclose(piece.linear_velocity, rigid, rtol=0, atol=HOST_RTOL * np.linalg.norm(rigid))
        assert np.allclose(piece.angular_velocity, w, rtol=0, atol=HOST_RTOL * np.linalg.norm(w))


def test_round_bodies_are_refit_to_conserve_momentum():
    """A sphere is cut from a 42-vertex polytope of its volume: its inertia differs slightly from
    the sphere's, so the pieces' spin is refit (fracture.py) instead of momentum being lost."""
    parent = _body("sphere")
    result = fracture_body(parent, pieces=8, seed=0)
    assert not result.exact and 0 < result.inertia_mismatch < 0.01
    spin = np.linalg.norm(result.bodies[0].angular_velocity) / np.linalg.norm(parent.angular_velocity)
    assert abs(spin - 1) < 0.01  # about the inertia mismatch


def test_outward_impulse_is_internal_and_adds_energy():
    parent = _body("box")
    still = fracture_body(parent, pieces=8, seed=2).bodies
    pushed = fracture_body(parent, pieces=8, seed=2, impulse=300.0).bodies
    kicks = [b.mass * (b.linear_velocity - a.linear_velocity) for a, b in zip(still, pushed)]
    assert sum(np.linalg.norm(j) for j in kicks) == pytest.approx(300.0, rel=1e-12)  # the total magnitude asked
    assert np.linalg.norm(sum(kicks)) <= HOST_RTOL * 300.0  # no net force
    for j, piece, parent_piece in zip(kicks, pushed, still):
        arm = piece.position - parent.position
        assert np.dot(j, arm) > 0  # outward
    energy = lambda bodies: sum(0.5 * b.mass * b.linear_velocity @ b.linear_velocity for b in bodies)  # noqa: E731
    assert energy(pushed) > energy(still)


@pytest.mark.parametrize("kind", ["box", "torus"])
def test_pieces_do_not_overlap_when_created(kind, coacd_cache):
    from sandbox.scene.decompose import OVERLAP_TOLERANCE

    pieces = fracture_body(_body(kind), pieces=8, seed=4).bodies
    hulls = [v for p in pieces for v in _world_vertices(p)]
    margin = Settings().contact_margin
    touch = TOUCH if kind == "box" else OVERLAP_TOLERANCE * np.ptp(np.vstack(hulls), axis=0).max()
    for i, a in enumerate(hulls):
        for b in hulls[i + 1:]:
            depth = penetration_depth(a, b)[0]
            assert depth <= margin  # the bound ...
            assert depth <= touch  # ... and in fact they only touch


def test_voronoi_pieces_are_seeded():
    parent = _body("box")
    a = fracture_body(parent, pieces=5, seed=11).bodies
    b = fracture_body(parent, pieces=5, seed=11).bodies
    c = fracture_body(parent, pieces=5, seed=12).bodies
    assert all(np.array_equal(x.position, y.position) for x, y in zip(a, b))
    assert not all(np.allclose(x.position, y.position) for x, y in zip(a, c))


def test_too_small_body_stays_whole():
    chip = _body("box", half_extents=[0.004, 0.004, 0.004])
    before = (chip.position.copy(), chip.mass)
    with pytest.raises(FractureError, match=r"too small to split into 8 pieces: .*fracture_min_piece_size is 10 mm"):
        fracture_body(chip, pieces=8, seed=0, min_piece_size=Settings().fracture_min_piece_size)
    assert np.array_equal(chip.position, before[0]) and chip.mass == before[1]


@pytest.mark.parametrize("kwargs,fragment", [
    ({"pieces": 1}, "pieces must be an integer from 2 to 64"),
    ({"pieces": 65}, "pieces must be an integer from 2 to 64"),
    ({"pieces": True}, "pieces must be an integer"),
    ({"seed": -1}, "seed must be an integer >= 0"),
    ({"impulse": float("nan")}, "impulse must be a finite number >= 0"),
    ({"impulse": -1.0}, "impulse must be a finite number >= 0"),
])
def test_fracture_arguments_are_checked(kwargs, fragment):
    with pytest.raises(FractureError, match=fragment):
        fracture_body(_body("box"), **kwargs)


# ---------------------------------------------------------------------------- world
SCENE = """# fracture test scene: every world test uses it, so the kernels compile once
description = "torus, L-block, a box, a breakable target, a ball, a 4 mm chip and a static post on a plane"

[world]
dt = 0.016666666666666666

[solver]
name = "pgs"
iterations = 10

[[static]]
shape = "plane"
normal = [0.0, 0.0, 1.0]

[[static]]
name = "post"
shape = "box"
half_extents = [0.2, 0.2, 0.5]
position = [-3.0, -3.0, 0.5]

[[body]]
name = "torus"
shape = "mesh"
generator = { kind = "torus", major_radius = 0.5, minor_radius = 0.15, sections = [16, 8] }
decomposition = { threshold = 0.2 }
position = [0.0, 0.0, 0.155]

[[body]]
name = "l_block"
shape = "mesh"
generator = { kind = "l_block" }
position = [2.5, 0.0, 0.205]

[[body]]
name = "box"
shape = "box"
half_extents = [0.3, 0.3, 0.3]
position = [5.0, 0.0, 0.3]

[[body]]
name = "target"
shape = "box"
half_extents = [0.4, 0.4, 0.4]
position = [0.0, 4.0, 0.4]
breakable = true
strength = 400.0

[[body]]
name = "ball"
shape = "sphere"
radius = 0.2
density = 3000.0
position = [-3.0, 4.0, 0.2]

[[body]]
name = "chip"
shape = "box"
half_extents = [0.002, 0.002, 0.002]
position = [5.0, 3.0, 0.002]
"""
TORUS_I, L_BLOCK_I, BOX_I, TARGET_I, BALL_I, CHIP_I, POST_I = range(7)


@pytest.fixture(scope="module")
def scene_path(tmp_path_factory, coacd_cache):
    path = tmp_path_factory.mktemp("fracture") / "fracture.toml"
    path.write_text(SCENE)
    return path


@pytest.fixture
def make_world(scene_path):
    from sandbox import World

    worlds = []

    def make(**kwargs):
        world = World(load_scene(scene_path), arch=TEST_ARCH, reserve_pieces=16, **kwargs)
        worlds.append(world)
        return world

    yield make
    for world in worlds:
        world.close()  # back to the pool: the next world reuses buffers and compiled kernels


def _world_momentum(world) -> tuple[np.ndarray, np.ndarray, float]:
    """Momentum of the world's dynamic bodies from its float32 state, summed in float64."""
    st, b, n = world.state(), world.buf.bodies, world.body_count
    inv_m = b.inv_mass.to_numpy()[:n].astype(np.float64)
    dyn = inv_m > 0
    m = 1.0 / inv_m[dyn]
    rot = quat_to_matrix(st["orientation"][dyn].astype(np.float64))
    inertia = b.inertia.to_numpy()[:n][dyn].astype(np.float64)
    x, v = st["position"][dyn].astype(np.float64), st["linear_velocity"][dyn].astype(np.float64)
    w = st["angular_velocity"][dyn].astype(np.float64)
    spin = np.einsum("nij,njk,nlk,nl->ni", rot, inertia, rot, w)
    return (m[:, None] * v).sum(0), (np.cross(x, m[:, None] * v) + spin).sum(0), float(m.sum())


def _lowest_point(world, i: int) -> float:
    """Lowest world z of body i's collision hulls at its current pose [m]."""
    spec, st = world.body_specs[i], world.state()
    rot = quat_to_matrix(st["orientation"][i].astype(np.float64))
    return min(float(((np.asarray(s.vertices) + s.local_position) @ rot.T + st["position"][i])[:, 2].min())
               for s in spec.shapes)


def test_torus_and_l_block_rest_stably_on_a_plane(make_world):
    world = make_world()
    s = world.settings
    # a resting body sits below the plane by the slop plus the soft contact's static sag g / omega^2
    # (omega = 2 pi contact_hertz); 0.1 mm more covers float32 and ten-iteration solver error
    sag = s.slop + 9.81 / (2 * math.pi * s.contact_hertz) ** 2 + 1e-4
    still = 0.01 * 9.81 * world.dt  # [m/s] a hundredth of what one step of gravity adds
    world.step(120)  # dropped 5 mm, then settling
    before = world.state()
    world.step(60)
    after = world.state()
    for i in (TORUS_I, L_BLOCK_I):
        assert -sag <= _lowest_point(world, i) <= 1e-4, world.body_specs[i].name
        assert np.linalg.norm(after["linear_velocity"][i]) < still
        assert np.linalg.norm(after["angular_velocity"][i]) < still / 0.5  # rim speed of a 0.5 m body
        tilt = 2 * math.degrees(math.acos(min(1.0, abs(float(after["orientation"][i][0])))))
        assert tilt < 0.5  # stays flat [deg]
        assert np.linalg.norm(after["position"][i] - before["position"][i]) < 1e-3  # no creep in the last second
    assert world.metrics()["max_penetration"] <= sag


def test_world_fracture_conserves_momentum_and_keeps_other_bodies(make_world):
    world = make_world()
    world.step(2)
    world.set_velocity([TORUS_I, BOX_I], linear=[1.0, -2.0, 3.0], angular=[0.5, -2.0, 1.0])
    caps = world.buf.caps
    p0, l0, m0 = _world_momentum(world)
    before = world.state()
    n = world.body_count
    new = world.fracture([TORUS_I, BOX_I], pieces=8, seed=1, impulse=50.0)
    torus_pieces = len(world.last_fracture[0].bodies)
    assert new[0] == TORUS_I and new[torus_pieces] == BOX_I  # piece 0 keeps the body's index
    assert sorted(new) == [TORUS_I, BOX_I] + list(range(n, world.body_count))
    assert world.body_count == n + torus_pieces - 1 + 7
    p1, l1, m1 = _world_momentum(world)
    assert abs(m1 - m0) <= WORLD_RTOL * m0
    assert np.linalg.norm(p1 - p0) <= WORLD_RTOL * np.linalg.norm(p0)
    assert np.linalg.norm(l1 - l0) <= WORLD_RTOL * np.linalg.norm(l0)
    after = world.state()
    for i in (L_BLOCK_I, TARGET_I, BALL_I, CHIP_I):  # untouched: bit for bit
        for key in after:
            assert np.array_equal(after[key][i], before[key][i]), (i, key)
    assert world.buf.caps == caps  # the reserve held them: no new buffers, no recompilation
    world.step(30)
    assert np.all(np.isfinite(world.state()["position"]))


def test_world_fracture_refuses_static_unknown_and_too_small(make_world):
    world = make_world()
    n, before = world.body_count, world.state()
    with pytest.raises(SandboxError, match=r"fracture: body 6 \('post'\) is static and cannot be fractured"):
        world.fracture(POST_I)
    with pytest.raises(SandboxError, match=r"fracture: no body 99 \(the world has bodies 0..6\)"):
        world.fracture(99)
    with pytest.raises(FractureError, match=r"fracture: body 5 \('chip'\) stays whole: too small to split"):
        world.fracture(CHIP_I, pieces=4)
    with pytest.raises(SandboxError, match="pieces must be an integer from 2 to 64"):
        world.fracture(BOX_I, pieces=100)
    assert world.body_count == n
    assert all(np.array_equal(world.state()[k], before[k]) for k in before)


def test_body_limit_names_the_setting(make_world):
    world = make_world(settings=Settings().replace(max_bodies=10))
    with pytest.raises(CapacityError, match=r"would make 14 bodies; this world holds at most 10 "
                                            r"\(Settings.max_bodies"):
        world.fracture(BOX_I, pieces=8)
    assert world.body_count == 7


def test_breakable_body_rests_then_breaks_on_impact_and_replays(make_world, scene_path, tmp_path):
    from sandbox.recording import Recorder, replay

    world = make_world()
    rec = Recorder(world, scene_path)
    for _ in range(30):
        world.step(1)
        rec.capture()
    target = world.body_specs[TARGET_I]
    weight = target.mass * 9.81 * world.dt  # [N s] what the floor passes to a resting body per step
    assert world.body_count == 7  # resting: no break
    # at rest the floor's manifold carries exactly the weight; after 0.5 s (five time constants
    # 2 zeta / omega of the over-damped contact) the settling left is ~1e-4 (measured 7e-5)
    assert world.impact_impulses()[TARGET_I] == pytest.approx(weight, rel=1e-3)
    assert weight < target.strength
    world.apply_event(EventSpec(time=0.5, kind="set_velocity", bodies=[BALL_I], linear_velocity=np.array([15.0, 0, 0])))
    for _ in range(30):
        world.step(1)
        rec.capture()
        if world.body_count > 7:
            break
    assert world.body_count == 7 + 7, "the 100 kg ball at 15 m/s should break the 512 kg target (strength 400 N s)"
    step, event = world.applied_events[-1]
    assert event.kind == "fracture" and event.cause == "impact" and event.bodies == [TARGET_I]
    assert sum(world.body_specs[i].mass for i in [TARGET_I] + list(range(7, 14))) == pytest.approx(target.mass, rel=1e-12)
    assert not any(b.breakable for b in world.body_specs)  # pieces do not break again
    for _ in range(10):
        world.step(1)
        rec.capture()
    path = tmp_path / "impact.sbrec"
    rec.save(path)
    world.close()
    result = replay(path, arch=TEST_ARCH)
    assert result["first_departure"] is None and result["max_difference"] == 0.0


def test_fracture_past_the_reserve_grows_buffers_keeping_state(make_world):
    world = make_world()
    world.step(2)
    world.set_velocity([BOX_I, TARGET_I], linear=[0.5, 0.0, 1.0], angular=[0.0, 1.0, 0.0])
    caps, before = world.buf.caps, world.state()
    p0, l0, m0 = _world_momentum(world)
    new = world.fracture([BOX_I, TARGET_I], pieces=40, seed=5)  # 78 new bodies and hulls: past the reserve of 16
    assert len(new) == 80 and world.body_count == 7 + 78
    assert world.buf.caps.bodies > caps.bodies and world.buf.caps.polys > caps.polys
    after = world.state()
    for i in (TORUS_I, L_BLOCK_I, BALL_I, CHIP_I):
        for key in after:
            assert np.array_equal(after[key][i], before[key][i]), (i, key)
    p1, l1, m1 = _world_momentum(world)
    assert abs(m1 - m0) <= WORLD_RTOL * m0
    assert np.linalg.norm(p1 - p0) <= WORLD_RTOL * np.linalg.norm(p0)
    assert np.linalg.norm(l1 - l0) <= WORLD_RTOL * np.linalg.norm(l0)
    world.step(5)
    assert np.all(np.isfinite(world.state()["position"]))


def test_impact_watch_runs_inside_every_iteration_launch_with_the_same_bits(make_world):
    """A scene with breakable bodies sums each substep's impulses inside the fused iteration
    loop (one thread, shared by the threads) as the stage-by-stage path does: the same
    impulses, the same break, the same bits."""
    results = {}
    for launch in ("per-stage", "one", "shared"):
        world = make_world(settings=Settings(iteration_launch=launch))
        world.step(30)
        impulses = world.impact_impulses()
        world.apply_event(EventSpec(time=0.5, kind="set_velocity", bodies=[BALL_I],
                                    linear_velocity=np.array([15.0, 0, 0])))
        world.step(20)
        assert world.body_count == 14, f"{launch}: the ball should break the target"
        results[launch] = (impulses, world.state())
    for launch in ("one", "shared"):
        np.testing.assert_array_equal(results["per-stage"][0], results[launch][0], err_msg=launch)
        for key, value in results["per-stage"][1].items():
            np.testing.assert_array_equal(value, results[launch][1][key], err_msg=f"{launch} {key}")
