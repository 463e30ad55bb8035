"""Solvers that degrade gracefully (issue 15): few iterations sag, they never fly; every
solver gives the same bounce; the split counts and the step's impulses mean what they say.

The stability limit behind the first tests is derived and measured in docs/method-notes.md
("Why low iteration counts blew up"): a schedule that steps a row by 1 / K~ can carry a
spring of at most omega h ~ kappa sqrt(S K / K~), so its static deflection is at least
F K~ h^2 / (S kappa^2). The preload (contact_spring.py) carries the load such a spring cannot
hold within its deflection, so tall piles no longer sag by that floor. Where a case still fails,
it is an expected failure with its measured figure, never a loosened criterion.
"""

import tomllib
from itertools import product
from pathlib import Path

import numpy as np
import pytest

from sandbox import SOLVERS, SandboxError, Scene, Settings, World
from sandbox.formulation import SweepPlan
from sandbox.scene.library import SCENES_DIR
from sandbox.settings import MAX_STEP_SWEEPS
from sandbox.solvers.contact_spring import LIGHT_LIMIT, STIFFNESS_LIMIT, row_params
from sandbox.solvers.schedule import Schedule

from tests.helpers import TEST_ARCH, box_body, plane, scene_dict

G = 9.81


def _combos(cases, known_failures):
    """Test params from tuples of arguments; a tuple in ``known_failures`` is a strict xfail with its reason."""
    for case in cases:
        reason = known_failures.get(case)
        marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
        yield pytest.param(*case, marks=marks, id="-".join(map(str, case)))


PYRAMID_TOP_TOLERANCE = 0.05
"""[m] The issue's criterion for the pyramid's top box (Rapier moves it 27 mm at 4 iterations)."""

PYRAMID_RESTING_KE = 1.0
"""[J] Mean kinetic energy of the last 60 frames of the 210-tonne pyramid: at rest, not ringing."""


def _settle(world, steps: int):
    """Step ``world`` ``steps`` times: (positions at the start, at the end, mean KE of the last 60
    steps, the farthest any body got sideways from its start [m] at any step)."""
    start = world.state()["position"]
    energies, sideways = [], 0.0
    for _ in range(steps):
        world.step(1)
        energies.append(world.metrics()["kinetic_energy"])
        moved = world.state()["position"] - start
        sideways = max(sideways, float(np.linalg.norm(moved[:, :2], axis=1).max()))
    return start, world.state()["position"], float(np.mean(energies[-60:])), sideways


@pytest.mark.parametrize("solver, iterations, steps", list(product(("mass-splitting", "block-mass-splitting"), (4, 8),
                                                                   (600, 1800))))
def test_split_schedules_keep_the_pyramid_standing(solver, iterations, steps):
    """pyramid_20: after 600 steps (the issue's horizon) and still after 1800 (30 s, long
    enough for a slow instability to show) the top box is within 5 cm and the pyramid is at rest.

    History, measured: with the preload (2026-11-25) the top sank 47 mm at 4 iterations (0.32 m
    before it); until 2026-11-28 the one-box-deep wall then buckled out of plane at 4 iterations
    (P-Delta on springs the stability limit keeps soft): mass splitting from step ~500, falling
    after ~1200, block mass splitting from the start (0.86 m at step 600), three strict expected
    failures. Since the split schedules sweep twice of each kind per substep at 4 iterations
    (Settings.step_sweeps) the top ends 43.4 / 41.2 mm down after 1800 steps (mean KE 8e-8 /
    5e-4 J): mostly the sag every schedule has (34.7 mm at 15 iterations), a margin of ~7 mm to
    the criterion (docs/method-notes.md)."""
    world = World(Scene.load(SCENES_DIR / "pyramid_20.toml"), solver=solver, iterations=iterations, arch=TEST_ARCH)
    start, end, ke, _ = _settle(world, steps)
    top = int(np.argmax(start[:, 2]))
    moved = float(np.linalg.norm(end[top] - start[top]))
    assert moved < PYRAMID_TOP_TOLERANCE and ke < PYRAMID_RESTING_KE, f"top moved {moved:.3f} m, KE {ke:.3g} J"


@pytest.mark.parametrize("solver", list(SOLVERS))
def test_every_schedule_sweeps_8_times_a_step_at_least(solver):
    """Settings.step_sweeps: below 8 iterations a substep of every schedule runs ceil(8 /
    iterations) sweeps of each kind; from 8 on, and under the paper formulation always, the plan
    is one sweep of each. The GPU's launch per substep unrolls them (up to MAX_STEP_SWEEPS of
    each; more falls back to a launch per stage), and the rows' springs take the stability limit
    of the sweeps run (kappa sqrt(S), S = biased + relax; a light body's rows under mass
    splitting and Jacobi count their Settings.ratio_sweeps biased sweeps more)."""
    schedule, info = Schedule(solver, {}), SOLVERS[solver]
    kappa = Settings().contact_stiffness_limit
    for iterations, each in ((1, 8), (2, 4), (3, 3), (4, 2), (5, 2), (7, 2), (8, 1), (15, 1), (30, 1)):
        plan = schedule.plan(Settings(), iterations)
        assert (plan.substeps, plan.biased, plan.relax) == (iterations, each, each), iterations
        params = row_params(Settings(), 1.0 / 60.0 / iterations, plan.biased, 1.0 / 60.0, (0.0, 0.0, -G),
                            info.stiffens_rocking, plan.ratio, info.stiffens_light_rows)
        assert params[STIFFNESS_LIMIT] == pytest.approx(kappa * np.sqrt(2.0 * each)), iterations
        light = 2 * each + (plan.ratio if info.stiffens_light_rows else 0)
        assert params[LIGHT_LIMIT] == pytest.approx(kappa * np.sqrt(light)), iterations
    assert schedule.plan(Settings(step_sweeps=0), 4).biased == 1
    assert schedule.plan(Settings(step_sweeps=12, sweeps=2), 4).biased == 3
    assert schedule.plan(Settings(formulation="paper"), 4) == SweepPlan(substeps=1, biased=4, relax=0)
    if solver != "pgs-colored":  # which launches once per colour
        per_substep = Settings(iteration_launch="per-substep")
        assert schedule.launch(per_substep, "cpu", 1000, schedule.plan(per_substep, 4)) == "per-substep"
        many = Settings(iteration_launch="per-substep", sweeps=MAX_STEP_SWEEPS + 1)
        assert schedule.launch(many, "cpu", 1000, schedule.plan(many, 4)) == "per-stage"


def test_a_former_setting_name_still_reads():
    """Recordings made before a rename replay (settings.RENAMED)."""
    assert Settings().replace(split_step_sweeps=3).step_sweeps == 3


@pytest.mark.parametrize("value", [-1, 65, 1.5, True, "8"])
def test_a_bad_step_sweeps_is_named(value):
    with pytest.raises(SandboxError, match="step_sweeps"):
        Settings(step_sweeps=value)


def test_the_web_default_scene_stands_at_4_iterations_with_mass_splitting():
    """The issue's first complaint: in the web sandbox, the iteration slider at 4 with mass
    splitting blew the playground's pyramid apart. 1800 steps (30 s) with sleeping off, so that
    nothing rests by decree: the 78-box pyramid's top stays within 5 cm and the scene comes to rest
    (measured 2026-11-25: 22.8 mm, 5.6e-8 J; 121 mm before the preload)."""
    world = World(Scene.load(SCENES_DIR / "playground.toml"), solver="mass-splitting", iterations=4, arch=TEST_ARCH)
    world.set_effects([e for e in world.effects if e != "sleeping"])
    start, end, ke, _ = _settle(world, 1800)
    pyramid = [i for i in range(len(start)) if "'pyramid_" in world.body_name(i)]
    top = pyramid[int(np.argmax(start[pyramid, 2]))]
    moved = float(np.linalg.norm(end[top] - start[top]))
    assert len(pyramid) == 78
    assert moved < PYRAMID_TOP_TOLERANCE and ke < PYRAMID_RESTING_KE, f"top moved {moved:.3f} m, KE {ke:.3g} J"


STACK_SWAY = {
    # measured 2026-11-25 (the same bits on 36f221a): the stack's sway grows ~7x per 100 steps
    # (KE 0.016 J at step 100, 7.6 J at 400, 3.6e4 J at 800) until it falls; 8 and 15 iterations
    # keep a bounded 0.01-0.3 J sway, mass splitting at 4 comes to rest (1e-10 J). The cause, found
    # later the same day: the column buckles (P-Delta) on springs few iterations keep soft, and serial
    # PGS's sweep order nudges it every step; mass splitting passes here only because its sweep never
    # moves a straight column sideways: nudged by 1 mm/s it falls at 4 and 8 iterations too
    # (tests/test_hard_cases.py, nudged_stack_20; docs/method-notes.md)
    # (2026-11-26, the visiting order turning every substep, visit_order.visited_point: the same
    # growth from a smaller seed: at 4 iterations drift 3 / 63 / 441 mm at steps 100 / 400 / 600,
    # fallen by 800)
    # (2026-11-27, a face resisting rocking more stiffly than its capped spring,
    # Settings.contact_rocking_stiffness: at 4 iterations the lean stops at ~7 mm and the stack
    # stays at rest through 1800 steps; at 2 it still topples, 1.26 m in 10 s)
    # (2026-11-28, four sweeps of each kind per substep at 2 iterations for every schedule,
    # Settings.step_sweeps: it no longer topples, it sways; coloured PGS's column, which fell at 2
    # iterations, 11 m/s, stands: 10 mm after 30 s)
    ("pgs", 2): "serial PGS at 2 iterations: the 20-box stack sways, never at rest (up to 74 / 87 mm sideways at "
                "steps 300 / 1200, KE 0.08-1.3 J; it toppled before, 1.1 m at step 400)",
}


@pytest.mark.parametrize("solver, iterations", list(_combos([*product(("pgs", "mass-splitting"), (2, 4)),
                                                              ("pgs-colored", 2)], STACK_SWAY)))
def test_the_20_box_stack_stays_standing_at_few_iterations(solver, iterations):
    """stack_20, 900 steps (15 s): no box leaves its column by more than 5 cm at any step and the
    stack is at rest at the end; few iterations may sag, a statically stable stack must not fall
    (nor sway: until 2026-11-28 only the end was read, and a sway of ~90 mm could pass between two
    swings)."""
    world = World(Scene.load(SCENES_DIR / "stack_20.toml"), solver=solver, iterations=iterations, arch=TEST_ARCH)
    _, _, ke, drift = _settle(world, 900)
    assert drift < PYRAMID_TOP_TOLERANCE and ke < PYRAMID_RESTING_KE, f"drift up to {drift:.3f} m, KE {ke:.3g} J"


@pytest.mark.parametrize("solver", ["mass-splitting", "jacobi"])
def test_a_nudged_column_stands_at_8_iterations(solver):
    """nudged_stack_20 (sandbox/hard_cases.py) at 8 iterations for 40 s, four times the hard
    case's window: these schedules' springs are capped at 193 rad/s there and the 20-box column
    needs ~270 in rotation (benchmarks/column_buckling.py). It buckled under its own weight (top
    54.6 mm at 10 s) until a face resisted rocking more stiffly than its capped spring
    (Settings.contact_rocking_stiffness; docs/method-notes.md, "The nudged column"); at 1.0 it
    still buckled, more slowly (4.8 mm at 10 s, 1.0 m at 36 s), hence the long window."""
    from sandbox.hard_cases import nudged_stack, run_case

    r = run_case(nudged_stack(), solver, 8, steps=2400, arch=TEST_ARCH)
    assert r.passed, r.figures


def _mechanical_energy(world, masses):
    st = world.state()
    m = world.metrics()
    return m["kinetic_energy"] + G * float(np.dot(masses, st["position"][:, 2])), st


@pytest.mark.parametrize("iterations", [1, 2, 4, 8, 15, 30])
@pytest.mark.parametrize("solver", list(SOLVERS))
def test_a_resting_block_never_gains_energy(solver, iterations):
    """A 2 x 2 x 3 block of unit boxes (1000 kg) placed 1 mm apart, 300 steps: kinetic plus
    potential energy never rises above its start, whatever the schedule and the count."""
    bodies = [box_body([1.001 * x, 1.001 * y, 0.5 + 1.001 * z]) for x in range(2) for y in range(2) for z in range(3)]
    world = World(Scene.from_dict(scene_dict(bodies)), solver=solver, iterations=iterations, arch=TEST_ARCH)
    masses = np.full(len(bodies), 1000.0)
    e0, _ = _mechanical_energy(world, masses)
    peak_gain, peak_speed = -np.inf, 0.0
    for _ in range(300):
        world.step(1)
        e, st = _mechanical_energy(world, masses)
        peak_gain = max(peak_gain, e - e0)
        peak_speed = max(peak_speed, float(np.linalg.norm(st["linear_velocity"], axis=1).max()))
    # the layers start 1 mm apart and settle that far and more (the energy falls by ~0.1 kJ, four
    # boxes dropping 1 mm and four 2 mm), far more than the float32 positions it is read from
    # round (one ulp, 1.2e-7 m at 1-2 m, is 1.2e-3 J of a 1000 kg box): a rise above the start
    # by 1e-3 J is energy the solver made
    assert peak_gain < 1e-3, f"gained {peak_gain:.3g} J (peak speed {peak_speed:.3g} m/s)"


def _bounce(solver, speed, gap, gravity, restitution=1.0, half=(0.5, 0.5, 0.5)):
    """A box (a unit cube unless ``half`` says otherwise) meeting a plane face-down at ``speed``
    from ``gap`` above it: (the speed it had just before touching, the fastest it moved away
    after)."""
    g = -G if gravity else 0.0
    body = box_body([0, 0, half[2] + gap], half, linear_velocity=[0.0, 0.0, -speed], restitution=restitution)
    d = scene_dict([body], statics=(dict(plane(), restitution=restitution),), gravity=(0.0, 0.0, g),
                   solver=solver, iterations=10)
    d["effects"] = ["friction", "restitution"]
    return _impact_and_rebound(World(Scene.from_dict(d), arch=TEST_ARCH))


def _impact_and_rebound(world, steps: int = 120):
    """Step ``world`` whose body 0 falls onto the ground: (the speed it had just before touching,
    the fastest it moved away after)."""
    before, after, landed = 0.0, 0.0, False
    for _ in range(steps):
        world.step(1)
        vz = float(world.state()["linear_velocity"][0, 2])
        if not landed and vz < 0.0:
            before = max(before, -vz)
        elif vz > 0.0:
            landed = True
            after = max(after, vz)
    return before, after


@pytest.mark.parametrize("solver", list(SOLVERS))
@pytest.mark.parametrize("speed, gap, gravity", [(5.0, 0.3, False), (5.0, 0.3, True), (0.0, 1.0, True),
                                                 (0.0, 2.0, True), (10.0, 0.5, True)])
def test_every_solver_gives_the_same_bounce(solver, speed, gap, gravity):
    """e = 1 against e = 1, from a gap larger than one step's travel (the impact arrives as a
    speculative contact): every schedule sends the cube back within 5 % of its impact speed."""
    before, after = _bounce(solver, speed, gap, gravity)
    assert before > 3.0 and after == pytest.approx(before, rel=0.05), f"impact {before:.3f} m/s, rebound {after:.3f}"


INELASTIC_CASES = [(5.0, 0.3, False), (5.0, 0.3, True), (0.0, 2.0, True), (10.0, 0.5, True)]


@pytest.mark.parametrize("solver", list(SOLVERS))
@pytest.mark.parametrize("speed, gap, gravity", INELASTIC_CASES)
def test_an_inelastic_cube_does_not_bounce(solver, speed, gap, gravity):
    """e = 0 against e = 0: every schedule keeps less than 5 % of the impact speed, the
    tolerance the elastic bounce is held to. Jacobi and mass splitting kept 20-24 % before an
    impact row's warm start was clamped (impact_carry.clamp_impact_carry), serial PGS 5.8 % of 5 m/s in
    zero gravity."""
    before, after = _bounce(solver, speed, gap, gravity, restitution=0.0)
    assert before > 3.0 and after < 0.05 * before, f"impact {before:.3f} m/s, rebound {after:.3f}"


@pytest.mark.parametrize("solver", list(SOLVERS))
def test_an_inelastic_tall_box_does_not_bounce(solver):
    """A 0.2 x 0.2 x 1 m box landing upright at 10 m/s, e = 0: its four corners are nearly one
    point, so their rows are nearly dependent; it keeps less than 5 % of the impact speed. Serial
    and coloured PGS and block mass splitting kept 5.9 % (0.60 m/s from 10.3) and tipped over
    while a sweep passed over an impact's points once: the corner solved first stopped it alone
    (visit_order.gauss_seidel_block)."""
    before, after = _bounce(solver, 10.0, 0.5, True, restitution=0.0, half=(0.1, 0.1, 0.5))
    assert before > 3.0 and after < 0.05 * before, f"impact {before:.3f} m/s, rebound {after:.3f}"


def test_only_an_impact_clamps_the_folded_warm_start():
    """A step clamps its folded carries (mass_splitting.clamp_folded_carries) only when a row closes
    faster than the restitution threshold and touches within the step (impact_carry.is_impact): a
    resting stack never does, so it keeps the plain folded loop; a cube dropped from 2 m does in the
    step it lands."""
    stack = World(Scene.from_dict(scene_dict([box_body([0, 0, 0.5 + k]) for k in range(3)])),
                  solver="mass-splitting", iterations=8, arch=TEST_ARCH)
    resting = []
    for _ in range(60):
        stack.step(1)
        resting.append(int(stack.buf.rows.impacts[None]))
    assert not any(resting)
    drop = World(Scene.from_dict(scene_dict([box_body([0, 0, 2.5])])), solver="mass-splitting", iterations=8,
                 arch=TEST_ARCH)
    flags = []
    for _ in range(60):
        drop.step(1)
        flags.append(int(drop.buf.rows.impacts[None]))
    # 2 m of fall take 0.639 s: the cube lands in step 39 (index 38, t = 0.633-0.650 s), the only
    # step whose start sees the ground closer than one step's travel at 6.2 m/s
    assert [k for k, f in enumerate(flags) if f] == [38]


@pytest.mark.parametrize("iterations", [1, 7, 20])
def test_the_step_impulse_sums_the_substeps(iterations):
    """A box at rest takes m g dt from the plane each step, however many substeps share it
    (it was reported as the last substep's impulse times their count)."""
    world = World(Scene.from_dict(scene_dict([box_body([0, 0, 0.5])])), solver="pgs", iterations=iterations,
                  arch=TEST_ARCH)
    world.track_impulses = True
    world.step(120)
    total = world.contacts(["impulse"])["impulse"][:, 0].sum()
    # relative 1e-3: float32 sums of ~1e2 N s per point
    assert total == pytest.approx(1000.0 * G / 60.0, rel=1e-3)


def test_impulses_are_only_read_while_tracked():
    world = World(Scene.from_dict(scene_dict([box_body([0, 0, 0.5])])), arch=TEST_ARCH)
    world.step(1)
    assert "impulse" not in world.contacts()
    with pytest.raises(Exception, match="track_impulses"):
        world.contacts(["impulse"])


def test_the_split_count_leaves_out_contacts_that_cannot_act():
    """A box resting on a plane with a wall 1 cm beside it (a speculative contact that neither
    touches, carries load nor closes within the step) is split in 4 (its ground corners), not 8."""
    wall = {"shape": "box", "half_extents": [0.5, 0.5, 0.5], "position": [1.01, 0.0, 0.5], "static": True}
    world = World(Scene.from_dict(scene_dict([box_body([0, 0, 0.5]), wall])), solver="mass-splitting",
                  iterations=4, arch=TEST_ARCH)
    world.step(30)
    c = world.contacts(["body_a", "body_b", "separation"])
    touching_box = [(a == 0 or b == 0) for a, b in zip(c["body_a"], c["body_b"])]
    assert sum(touching_box) == 8  # 4 ground corners and 4 speculative wall corners
    assert int(world.buf.blocks.active_count[0]) == 4


def test_support_points_that_only_come_near_take_no_share_of_the_preload():
    """Three 1 mm cubes at 8 iterations under mass splitting: the middle cube's points against
    the ground, ~0.3 mm below it and carrying nothing, once counted as support points beside the
    four that carried it, so each loaded row got half its preload and the cube rested 0.7 mm
    (70 %) inside the bottom one. The hard case's own criterion: penetration < 5 % of the size
    over the last half, drift < 2 %."""
    from sandbox.hard_cases import run_case, scaled_stack

    result = run_case(scaled_stack(0.001), "mass-splitting", 8, arch=TEST_ARCH)
    assert result.passed, result.figures


@pytest.mark.parametrize("iterations", [8, 30])
def test_projected_jacobi_bounds_its_relaxation_by_the_busiest_body(iterations):
    """The card house's planks touch at up to 40 points: a fixed relaxation of 0.25 (a global
    split of 4) overshoots such a body tenfold, and the error grew every sweep (1580 m/s by step 5
    at 30 iterations, a plank at 23 m/s at 15). The default Jacobi takes the split mass splitting
    gives its busiest body as the one global factor; an explicit relaxation is taken as given."""
    from sandbox.hard_cases import FLYING_SPEED, all_cases, run_case

    case = {c.name: c for c in all_cases()}["leaning_planks"]
    result = run_case(case, "jacobi", iterations, arch=TEST_ARCH)
    assert result.peak_speed < FLYING_SPEED, result.figures
    if iterations == 30:
        assert result.passed, result.figures

    scene = Scene.load(SCENES_DIR / "leaning_planks.toml")
    bounded = World(scene, solver="jacobi", iterations=iterations, arch=TEST_ARCH)
    fixed = World(scene, solver="jacobi", iterations=iterations, arch=TEST_ARCH, relaxation=0.25)
    bounded.step(1)
    fixed.step(1)
    busiest = int(bounded.buf.blocks.adj_count.to_numpy()[:bounded.body_count].max())
    split = busiest / bounded.settings.split_relaxation
    assert busiest > 8
    assert float(bounded.buf.blocks.scale[0]) == pytest.approx(max(4.0, split), rel=1e-6)
    assert float(fixed.buf.blocks.scale[0]) == pytest.approx(4.0, rel=1e-6)


def test_placed_within_moves_each_body_sideways_by_at_most_the_jitter():
    """The ensemble's placements (benchmarks/card_house_ensemble.py): seeded, sideways only, within
    the jitter, and the case itself untouched."""
    from sandbox.hard_cases import leaning_planks, placed_within

    case = leaning_planks()
    start = [b["position"] for b in tomllib.loads(case.scene.read_text())["body"]]
    placed = placed_within(case, 1e-5, seed=3)
    moved = np.array([b["position"] for b in placed.scene["body"]]) - np.array(start)
    assert np.abs(moved[:, :2]).max() <= 1e-5 and np.abs(moved[:, :2]).min() > 0.0
    assert np.all(moved[:, 2] == 0.0)
    assert placed_within(case, 1e-5, seed=3).scene == placed.scene != placed_within(case, 1e-5, seed=4).scene
    assert isinstance(case.scene, Path) and placed.steps == case.steps and placed.judge is case.judge


CARD_HOUSE_LUCK = ("projected Jacobi's card house at 15 iterations stands as shipped (0.16 mm) but falls in 3 of 8 "
                   "placements within 10 um (1.3-1.6 m; benchmarks/card_house_ensemble.py): a card's top joint "
                   "slides at its friction cone under sweeps that do not converge; two sweeps a substep on the same "
                   "springs hold all 9 (docs/method-notes.md, \"The card house at 8 iterations\")")


@pytest.mark.parametrize("solver, iterations", [
    ("pgs", 8), ("mass-splitting", 8), ("mass-splitting", 15), ("block-mass-splitting", 15),
    pytest.param("jacobi", 15, marks=pytest.mark.xfail(strict=True, reason=CARD_HOUSE_LUCK))])
def test_the_card_house_stands_wherever_it_is_placed_within_10_um(solver, iterations):
    """One history of a marginal case passes or fails by rounding (block mass splitting's card house
    at 8 iterations went from 0.7 mm to a collapse with a new contact order). A schedule that holds
    the card house holds it placed a few micrometres differently too: four seeded placements, the
    case's own criterion (no card moves more than 5 mm after the first second)."""
    from sandbox.hard_cases import leaning_planks, placed_within, run_case

    for seed in (1, 2, 3, 4):
        result = run_case(placed_within(leaning_planks(), 1e-5, seed), solver, iterations, arch=TEST_ARCH)
        assert result.passed, f"seed {seed}: {result.figures}"


def test_a_jacobi_bounce_beside_a_busy_body_keeps_its_speed():
    """Projected Jacobi's one factor is its busiest body's: beside a resting 27-box block (whose
    middle box touches at 80 points, a factor of 44) an e = 1 cube from the bounce test above
    must still come back within 5 % of its impact speed. It left at 6.55 m/s from 5.49 while the
    step after the bounce warm started the leaving corners with the impact's impulse, which
    sweeps at that factor take back ~4 / 44 a sweep (impact_carry.clamp_impact_carry)."""
    cube = box_body([0, 0, 0.8], linear_velocity=[0.0, 0.0, -5.0], restitution=1.0)
    block = [box_body([10.0 + x, y, 0.5 + z], restitution=0.0) for x in range(3) for y in range(3) for z in range(3)]
    d = scene_dict([cube] + block, statics=(dict(plane(), restitution=1.0),), gravity=(0.0, 0.0, -G),
                   solver="jacobi", iterations=10)
    d["effects"] = ["friction", "restitution"]
    before, after = _impact_and_rebound(World(Scene.from_dict(d), arch=TEST_ARCH))
    assert before > 3.0 and after == pytest.approx(before, rel=0.05), f"impact {before:.3f} m/s, rebound {after:.3f}"
