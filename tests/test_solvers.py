"""The parallel solvers against the serial PGS reference (issue: parallel contact solvers)."""

import numpy as np
import pytest

from sandbox import Scene, Settings, SimulationError, World

from tests.helpers import TEST_ARCH, box_body, compiled_kernel_count, plane, scene_dict

PARALLEL = ["pgs-colored", "jacobi", "mass-splitting", "block-mass-splitting"]
DETERMINISTIC = ["pgs", "pgs-colored", "jacobi", "mass-splitting", "block-mass-splitting"]


def _sphere(position, radius=0.5, density=1000.0):
    return {"shape": "sphere", "radius": radius, "position": list(position), "density": density}


SMALL_PROBLEMS = {
    "box_on_plane": [box_body([0, 0, 0.5])],
    "three_box_stack": [box_body([0, 0, 0.5 + i]) for i in range(3)],
    "box_on_four_spheres": [
        _sphere([-0.6, -0.6, 0.25], radius=0.25),
        _sphere([0.6, -0.6, 0.25], radius=0.25),
        _sphere([-0.6, 0.6, 0.25], radius=0.25),
        _sphere([0.6, 0.6, 0.25], radius=0.25),
        box_body([0, 0, 1.0], half=(1.0, 1.0, 0.5)),
    ],
}


def _one_step(bodies, solver, sweeps):
    """One step from rest with no warm start, as one substep whose velocity-level problem
    (soft, then rigid relax) is swept `sweeps` times."""
    scene = Scene.from_dict(scene_dict(bodies))
    world = World(scene, solver=solver, iterations=1, arch=TEST_ARCH, settings=Settings(warm_start=0.0, sweeps=sweeps))
    world.track_impulses = True
    world.step(1)
    c = world.contacts()
    per_manifold = np.zeros((c["manifold"].max() + 1, 3))
    force = c["normal"] * c["impulse"][:, :1]  # the normal impulses, as vectors
    np.add.at(per_manifold, c["manifold"], force)
    return per_manifold, world.state()["linear_velocity"]


@pytest.mark.parametrize("problem", sorted(SMALL_PROBLEMS))
@pytest.mark.parametrize("solver", ["mass-splitting", "block-mass-splitting"])
def test_mass_splitting_converges_to_pgs(problem, solver):
    """Given enough iterations, the split solvers reach PGS's solution: same impulse per body
    pair and same velocities (the per-point split of a statically indeterminate manifold is
    not unique, its resultant is)."""
    ref_imp, ref_vel = _one_step(SMALL_PROBLEMS[problem], "pgs", 500)
    imp, vel = _one_step(SMALL_PROBLEMS[problem], solver, 3000)
    scale = np.abs(ref_imp).max()
    assert np.abs(imp - ref_imp).max() / scale < 1e-4
    # [m/s] what that impulse tolerance can change the lightest body's velocity by (measured
    # 2026-11-27: at most 2.3e-7 m/s, impulses within 1.5e-6 of the largest)
    lightest = min(b.mass for b in Scene.from_dict(scene_dict(SMALL_PROBLEMS[problem])).bodies)
    assert np.abs(vel - ref_vel).max() < 1e-4 * scale / lightest


TALL = (0.2, 0.2, 1.0)
JACOBI_PROBLEMS = {
    "tall_box_on_plane": [box_body([0, 0, 1.0], half=TALL)],
    "two_tall_boxes": [box_body([0, 0, 1.0], half=TALL), box_body([0, 0, 3.0], half=TALL)],
}


@pytest.mark.parametrize("problem", sorted(JACOBI_PROBLEMS))
def test_plain_jacobi_does_not_converge_where_mass_splitting_does(problem):
    """A tall box resting on 4 points: the unit response of one corner is 1.23/m, so plain
    Jacobi (relaxation 1) gives each corner the impulse that would stop the box alone, 3.25x too
    much in total; next sweep every corner sees the box flying off and drops to zero; the iterate
    cycles and the residual never falls (method.md 1.3, docs/method-notes.md). Mass splitting
    divides the box among its 4 corners and converges. (A unit cube is the lucky exception:
    its corner response is exactly 4/m, so plain Jacobi is exact there.) One step from rest
    without warm starting, so each solver starts from lambda = 0."""
    from sandbox import Settings

    scene = Scene.from_dict(scene_dict(JACOBI_PROBLEMS[problem]))
    residual = {}
    for solver, opts in (("jacobi", {"relaxation": 1.0}), ("mass-splitting", {})):
        world = World(scene, solver=solver, iterations=1, arch=TEST_ARCH, settings=Settings(warm_start=0.0, sweeps=400),
                      **opts)
        try:
            world.step(1)
            residual[solver] = world.metrics()["residual_rms"]
        except SimulationError:  # diverged to inf/NaN: the guard stopped the step
            residual[solver] = np.inf
    gravity_velocity = 9.81 / 60.0  # [m/s] what the contacts must cancel in one step
    assert residual["mass-splitting"] < 1e-4 * gravity_velocity
    assert residual["jacobi"] > 0.1 * gravity_velocity


def _pile_300():
    return {
        "world": {"dt": 1.0 / 60.0},
        "solver": {"name": "pgs", "iterations": 8},
        "static": [plane()],
        "generate": [{
            "kind": "grid", "counts": [5, 6, 10], "spacing": 1.4, "origin": [-2.8, -3.5, 0.8],
            "shapes": ["box"], "half_extent_range": [0.2, 0.4], "orientation": "random", "seed": 7,
        }],
    }


@pytest.mark.parametrize("solver", DETERMINISTIC)
def test_two_runs_are_bitwise_identical(solver):
    scene = Scene.from_dict(_pile_300())
    assert len(scene.bodies) == 300
    states = []
    for _ in range(2):
        world = World(scene, solver=solver, iterations=8, arch=TEST_ARCH)
        world.step(90)
        states.append(world.state())
        assert world.metrics()["contacts"] > 300  # the pile has landed and touches
    for key in states[0]:
        np.testing.assert_array_equal(states[0][key], states[1][key], err_msg=key)


def test_set_solver_keeps_world_and_warm_start():
    scene = Scene.from_dict(scene_dict([box_body([0, 0, 0.5 + i]) for i in range(5)]))
    world = World(scene, solver="pgs", iterations=10, arch=TEST_ARCH)
    world.track_impulses = True
    world.step(60)
    before = world.state()["position"].copy()
    lam_before = world.contacts()["impulse"][:, 0].sum()
    world.set_solver("mass-splitting", iterations=20)
    world.step(1)
    # warm-started: the stack keeps carrying its weight on the first step after the switch
    assert world.contacts()["impulse"][:, 0].sum() == pytest.approx(lam_before, rel=0.05)
    assert np.abs(world.state()["position"] - before).max() < 2e-3
    with pytest.raises(Exception) as err:
        world.set_solver("no-such-solver")
    assert "unknown solver" in str(err.value)


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting", "block-mass-splitting"])
def test_residual_falls_with_sweeps_on_a_frozen_problem(solver):
    """Convergence curve on one step's problem (iterations = 1, many sweeps, no warm start):
    the residual keeps falling. Mass splitting is the slow one (the paper's 'slower
    convergence'): on a 3-box stack, 1e-3 of its first-sweep value takes it ~1000 sweeps."""
    from sandbox import Settings

    scene = Scene.from_dict(scene_dict(SMALL_PROBLEMS["three_box_stack"]))
    world = World(scene, solver=solver, iterations=1, arch=TEST_ARCH, settings=Settings(warm_start=0.0, sweeps=1500))
    world.record_residuals = True
    world.step(1)
    curve = np.asarray(world.residual_history)
    assert len(curve) == 1500 and np.all(np.isfinite(curve))
    assert curve[-1] < 1e-3 * curve[0]
    assert curve[1000] < curve[100] < curve[10]


@pytest.mark.parametrize("solver", DETERMINISTIC)
def test_iteration_launches_give_the_same_bits(solver):
    """The iteration loop in one launch (serialized), in one launch shared by the CPU threads,
    in one launch per substep (parallel phases) and stage by stage (a launch per phase, as
    profiled) is the same computation: no float atomics and fixed-order gathers, so the
    states agree bit for bit (solvers/substep.py). "one" and "shared" here also run the step's
    set-up, solve and store as one launch (step_kernels.solve_step_in_order, solve_step_shared:
    no bounce in this pile). The landing pile has impact rows, whose steps clamp their folded
    carries after each carrying sweep (mass_splitting.clamp_folded_carries), and resting steps."""
    from sandbox import Settings

    scene = Scene.from_dict(_pile_300())
    opts = {"shuffle": True} if solver == "pgs-colored" else {}
    states = {}
    launches = ("per-stage", "one", "shared", "per-substep")
    for launch in launches:
        world = World(scene, solver=solver, iterations=4, arch=TEST_ARCH, settings=Settings(iteration_launch=launch),
                      **opts)
        impact_steps = 0
        for _ in range(75):
            world.step(1)
            impact_steps += int(world.buf.rows.impacts[None])
        assert world.metrics()["contacts"] > 300
        assert 0 < impact_steps < 75
        states[launch] = world.state()
    for launch in launches[1:]:
        for key in states["per-stage"]:
            np.testing.assert_array_equal(states["per-stage"][key], states[launch][key], err_msg=f"{launch} {key}")


@pytest.mark.parametrize("solver", ["jacobi", "mass-splitting", "block-mass-splitting"])
def test_a_fast_push_relaxes_twice_in_every_launch(solver):
    """Boxes placed 30 % into each other push out faster than ``relax_push_speed`` = 0.5 m/s (their
    push is capped at ``overlap_push_speed``, 1 m/s): the Jacobi family's substeps then run a
    second relax sweep (solvers/substep.py). Every launch
    mode takes the same branch, so the states agree bit for bit, and the sweep is really run
    (the state differs with the option off, its default)."""
    from sandbox import Settings
    from sandbox.hard_cases import deep_overlap

    scene = Scene.from_dict(deep_overlap().scene, source="deep_overlap")
    states = {}
    for launch in ("per-stage", "one", "shared", "per-substep"):
        world = World(scene, solver=solver, iterations=15, arch=TEST_ARCH,
                      settings=Settings(iteration_launch=launch, relax_push_speed=0.5))
        world.step(4)
        states[launch] = world.state()
    for launch in ("one", "shared", "per-substep"):
        for key in states["per-stage"]:
            np.testing.assert_array_equal(states["per-stage"][key], states[launch][key], err_msg=f"{launch} {key}")
    world = World(scene, solver=solver, iterations=15, arch=TEST_ARCH)
    world.step(4)
    assert not np.array_equal(world.state()["linear_velocity"], states["one"]["linear_velocity"])


@pytest.mark.parametrize("solver, iterations", [("jacobi", 15), ("mass-splitting", 15), ("block-mass-splitting", 15),
                                                ("mass-splitting", 2), ("pgs", 2)])
def test_an_impact_and_a_fast_push_in_every_launch(solver, iterations):
    """Both of a substep's extra passes at once: a box thrown at 8 m/s onto the overlapping boxes
    of the test above lands in an impact step (its carries clamped after every carrying sweep,
    mass_splitting.clamp_folded_carries) while their push-out earns second relax sweeps; the team-shared
    loop walks its most phases there. Every launch mode gives the same bits, also at 2
    iterations, where a substep runs 4 sweeps of each kind (Settings.step_sweeps; serial PGS's
    per-substep launch unrolls them too)."""
    from sandbox import Settings
    from sandbox.hard_cases import deep_overlap

    d = deep_overlap().scene
    d["body"] = list(d["body"]) + [box_body([0.0, 0.0, 3.3], linear_velocity=[0.0, 0.0, -8.0])]
    scene = Scene.from_dict(d, source="deep_overlap_and_a_throw")
    states = {}
    for launch in ("per-stage", "one", "shared", "per-substep"):
        world = World(scene, solver=solver, iterations=iterations, arch=TEST_ARCH,
                      settings=Settings(iteration_launch=launch, relax_push_speed=0.5))
        impact_steps = 0
        for _ in range(4):
            world.step(1)
            impact_steps += int(world.buf.rows.impacts[None])
        assert impact_steps > 0
        states[launch] = world.state()
    for launch in ("one", "shared", "per-substep"):
        for key in states["per-stage"]:
            np.testing.assert_array_equal(states["per-stage"][key], states[launch][key], err_msg=f"{launch} {key}")


@pytest.mark.parametrize("solver", ["mass-splitting", "pgs-colored"])
def test_shared_iteration_loop_with_any_team_size(solver, monkeypatch):
    """The shared loop's result does not depend on how many members the team has or on
    which member solves which chunk: a team of one (nothing to wait for but itself) and a
    team of three on Taichi's two threads (a member may start only after another has run
    the whole loop; it must find every phase done, not wait for anyone) give the bits of
    the one-thread loop, and neither hangs."""
    from sandbox import Settings
    from sandbox.solvers import team

    scene = Scene.from_dict(_pile_300())
    opts = {"shuffle": True} if solver == "pgs-colored" else {}
    states = {}
    for label, launch, members in (("one", "one", None), ("team of 1", "shared", 1), ("team of 3", "shared", 3)):
        if members is not None:
            monkeypatch.setattr(team, "cpu_threads", lambda n=members: n)
        world = World(scene, solver=solver, iterations=4, arch=TEST_ARCH, settings=Settings(iteration_launch=launch),
                      **opts)
        world.step(40)
        states[label] = world.state()
    for label in ("team of 1", "team of 3"):
        for key in states["one"]:
            np.testing.assert_array_equal(states["one"][key], states[label][key], err_msg=f"{label} {key}")


@pytest.mark.parametrize("solver", ["pgs", "mass-splitting"])
def test_fused_step_kernels_give_the_profiled_bits(solver):
    """The once-per-step stages fused into three launches (step_kernels.py: state save to
    narrowphase; adjacency, then rows + matching + responses in one loop over the points;
    finite check and contact store) compute what the separate, profiled kernels do."""
    scene = Scene.from_dict(_pile_300())
    states = []
    for profile in (True, False):
        world = World(scene, solver=solver, iterations=4, arch=TEST_ARCH, profile=profile)
        world.step(60)
        assert world.metrics()["contacts"] > 300
        states.append(world.state())
    for key in states[0]:
        np.testing.assert_array_equal(states[0][key], states[1][key], err_msg=key)


@pytest.mark.parametrize("solver, launch", [("mass-splitting", "one"), ("mass-splitting", "per-substep"),
                                            ("pgs-colored", "auto")],
                         ids=["one-launch solve", "a launch per substep (a GPU's)", "colouring in launches"])
def test_a_step_timed_launch_by_launch_is_the_fused_step(solver, launch):
    """The web sandbox samples a step launch by launch (profile.py): the fused step's own kernels
    with a sync between them, so sampling compiles nothing new (a per-stage step compiled a
    second set, a 4-11 s pause of the running world), gives the same bits, and times every
    launch under its stage group. The launch is named: "auto" is a launch per substep on a GPU."""
    scene = Scene.from_dict(_pile_300())
    settings = Settings(iteration_launch=launch)
    plain = World(scene, solver=solver, iterations=4, arch=TEST_ARCH, settings=settings)
    sampled = World(scene, solver=solver, iterations=4, arch=TEST_ARCH, settings=settings)
    sampled.profiler.per_stage = False
    plain.step(30)
    sampled.step(29)
    compiled = compiled_kernel_count()
    sampled.profiler.reset()
    sampled.profiler.enabled = True
    sampled.step(1)
    sampled.profiler.enabled = False
    assert compiled_kernel_count() == compiled
    timing = sampled.timing_ms()
    assert timing["collide"] > 0.0 and timing["solve"] > 0.0
    assert (timing["iterate"] > 0.0) == (launch != "one")  # else set-up, loop and store are launches apart
    assert timing["total"] == pytest.approx(timing["collide"] + timing["solve"] + timing["integrate"])
    for key, value in plain.state().items():
        np.testing.assert_array_equal(value, sampled.state()[key], err_msg=key)
