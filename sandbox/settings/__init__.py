"""Every tunable of the contact pipeline, with its unit, default and consequence.

No slop, margin or bias factor is written as a literal inside a kernel: kernels
read these values from the ``Settings`` instance a world was built with
(house rule 7, after Jolt's ``PhysicsSettings.h``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from ..errors import SandboxError
from .domains import FORMULATIONS, ITERATION_LAUNCHES, MAX_RATIO_SWEEPS, MAX_STEP_SWEEPS, check_settings

__all__ = ["FORMULATIONS", "ITERATION_LAUNCHES", "MAX_RATIO_SWEEPS", "MAX_STEP_SWEEPS", "RENAMED", "Settings"]

RENAMED = {"split_step_sweeps": "step_sweeps"}
"""Former names of settings, read as the new ones (Settings.replace)."""


@dataclass(frozen=True)
class Settings:
    contact_margin: float = 0.02
    """[m] Speculative distance: shape pairs closer than this produce contacts.
    Larger keeps resting contacts from flickering and catches faster bodies
    (speculative CCD); too large adds contacts that carry no load but still
    count in the mass-splitting divisor n_b. Per pair it is capped at a quarter
    of the smaller shape's bounding radius so millimetre bodies stay sane."""

    speculative_contacts: bool = True
    """Speculative contacts (continuous collision, Catto's speculative CCD): a moving body's
    bounds and its pairs' contact margins grow by how far it can move in the step (|v| dt +
    |w| r dt), so a fast body meets what lies in its path as a contact with a gap instead of
    passing through it. False compiles that away (effects.py): margins are ``contact_margin``
    only, and a body moving more than its size in a step can tunnel. Scene key:
    ``[world] speculative_contacts``."""

    speculative_speed: float = 0.0
    """[m/s] With speculative contacts, only bodies whose speed bound (|v| + |w| r) exceeds this
    get the swept growth; slower ones keep the plain ``contact_margin``, which already covers
    what they can move in a step (so the growth would only add contacts). 0: every moving body
    (the default). Scene key: ``[world] speculative_speed``."""

    slop: float = 0.0005
    """[m] Penetration tolerated without position correction. Lower tightens
    resting overlap; higher lets stacks sink visibly (a 20-box stack sinks by
    up to 20 slops). Speculative contacts keep resting points alive, so a small
    slop does not make contacts flicker."""

    contact_hertz: float = 30.0
    """[Hz] Stiffness of the position correction: penetration beyond the slop is
    removed like a spring of this frequency (soft contacts, Box2D v3 / Catto's
    "soft step"), relative to the contact's effective mass. A scene may set its own
    (``[world] contact_hertz``). Higher pushes overlaps out faster and lets stacks
    sink less (a contact under a load F deflects F K / omega^2, K its unit response).
    Each contact row is capped at what its schedule can carry stably
    (``contact_stiffness_limit``) and stiffened where its load would press it further
    than ``contact_deflection`` allows; 30 Hz is Box2D v3's default."""

    contact_stiffness_limit: float = 0.6
    """[1] kappa of the stability limit every contact row's spring is capped at:
    omega h <= kappa sqrt(S K / K~), with h the substep, S the sweeps per substep
    (biased + relax), K the row's unit response and K~ the one the schedule divides by
    (K for PGS, about n_b K for mass splitting). Why: the soft spring is only damped when
    the row solve converges within the substep; a sweep that steps by 1 / K~ lags the
    spring by ~K~ / gamma sweeps, and past this limit the lag feeds energy into the
    structure's slowest modes (docs/method-notes.md, "Why low iteration counts blew up":
    measured onset kappa ~0.7 for PGS, mass splitting and block mass splitting alike on
    the 210-box pyramid). Higher is stiffer and closer to that onset; lower sags more.
    The limit also bounds every stable one-sweep schedule's static deflection from below
    (F K~ h^2 / (S kappa^2)): few iterations sag, they never fly. 0 turns the limit off
    (benchmarks/stiffness_limit.py scans the unlimited springs)."""

    ratio_sweeps: int = 6
    """[1] Biased sweeps more per substep, under the Jacobi family (projected Jacobi, mass splitting,
    block mass splitting), for the contacts of a body resting against one ``ratio_mass`` times
    heavier or more: those rows alone are swept again, and under mass splitting and Jacobi their
    springs take the stiffness limit of the sweeps they get (``contact_stiffness_limit``,
    contact_spring.light_sweeps: kappa sqrt(2 + 6) at 8 iterations and more). Why: a split sweep
    moves a heavy body's load into a light one by a 1 / n_b share per sweep, and the capped spring
    that one sweep can hold lets a 1000 kg box on 100, 10 and 1 kg boxes sink 61.5 mm at 8
    iterations; the rows need both the sweeps and the stiffness those sweeps carry (either alone:
    58-962 mm; docs/method-notes.md, "The 1:1000 column at 8 iterations"). 6: 5.8 mm there, and the
    column struck from above at 15 iterations comes back to rest (its transient sinks 16.5 mm; 5.2
    and 8.5 mm since the light rows' own damping, ``light_damping_ratio``);
    2 with the limit its sweeps carry: 21.3 mm, the struck column sinks 35.9 mm (docs/method-notes.md,
    "A kicked column: light rows stiffer than their sweeps"). Its price is in scenes with such pairs
    (confined_pile, 35 % of its points: the iteration loop 4.7 -> 8.6 ms/step at 15 iterations);
    a scene without such a pair runs none (0 turns them off). Ignored by the PGS solvers and under
    the paper formulation."""

    step_sweeps: int = 8
    """[1] The fewest sweeps of each kind a step runs, under every schedule of the soft step: at
    fewer iterations each substep runs ceil(``step_sweeps`` / iterations) biased sweeps before the
    position update and as many relax sweeps after it (at least ``sweeps``), and its springs take
    the stiffness limit of those sweeps (``contact_stiffness_limit``). Why: a tall structure needs
    springs stiffer than one sweep per substep can carry at few iterations (a 20-box column buckles
    below ~270 rad/s; the limit is kappa sqrt(S) / h). With one sweep of each kind per substep
    pyramid_20's one-box-deep wall buckled and fell at 4 iterations under both split schedules, and
    the 20-box column and the arch fell at 1 or 2 under every schedule, their tops reaching 11-20 m/s
    (docs/method-notes.md, "Few iterations: a floor on the split schedules' sweeps" and "Few
    iterations: the floor on every schedule"; at 1 iteration it delays a column's fall, it does not
    stop it). The relax sweeps come with them: more biased than relax sweeps left
    push-out velocity the one relax sweep did not take back, and resting columns gained energy at 1
    and 2 iterations (up to 1.5e4 J). It also keeps the schedules' work equal at equal iteration
    counts. 8: from 8 iterations on nothing changes (every schedule then is Rapier's scheme, one
    sweep of each kind per substep); at 4 a substep sweeps twice of each kind, at 2 four times, at 1
    eight times, and costs that much more (benchmarks/step_bench.py prices it with ``--set
    step_sweeps=0``). On a GPU each count compiles its own per-substep launch (unrolled, at most
    ``MAX_STEP_SWEEPS`` of each kind): a first step at a new iteration count below 8 pays one
    compile. 0 turns it off. Ignored under the paper formulation (whose iterations are its sweeps).
    Named ``split_step_sweeps`` on 2026-11-28, when it was the Jacobi family's alone."""

    ratio_mass: float = 5.0
    """[1] Mass ratio at which the lighter body of a touching pair of dynamic bodies has its
    contacts swept ``ratio_sweeps`` times more (> 1: of two equal masses neither is lighter)."""

    contact_rocking_stiffness: float = 1.5
    """[1] How much stiffer than its capped spring a contact face is against rocking, at most:
    where the stability limit caps a row's spring below the one asked for, the row's push-out
    reads its depth beyond the mean depth of its manifold's touching points up to this many
    times over (contact_spring.rocking_share), so a face resists turning on its support as if
    its spring were up to 1 + this times stiffer, while its compression (all points alike)
    keeps the capped spring. Why: a tall column on springs buckles under its own weight
    (P-Delta) when they are too soft in rotation, however stable the solve; a 20-box column
    needs omega >= ~270 rad/s and mass splitting at 8 iterations may carry only 193
    (benchmarks/column_buckling.py; docs/method-notes.md, "The nudged column at 8
    iterations"). The column model (benchmarks/stiffness_limit.py buckling) puts its critical
    spring at 283 rad/s about a face's middle, i.e. this above 1.15: 1.0 (273 rad/s) only slowed
    that column's fall (1 m at 36 s), 1.25 and 1.5 hold it through 40 s. Raising the limit instead rings compressed stacks and
    drops the card house. Rows the limit does not cap are untouched (PGS at 8 iterations and
    more, most rows at 15), and so is block mass splitting (SolverInfo.stiffens_rocking says
    why). 0 turns it off."""

    contact_damping_ratio: float = 10.0
    """[1] Damping ratio of that spring. Heavily over-damped (10) so a correction
    never overshoots; together with the regularisation it brings, this is what
    keeps warm-started stacks from ringing when the solver has not converged."""

    light_damping_ratio: float = 30.0
    """[1] Damping ratio of the contact springs of a light body (one resting against a body
    ``ratio_mass`` times heavier or more, whose rows take ``ratio_sweeps`` more sweeps), under every
    schedule of the Jacobi family; the other rows, and every row under the PGS solvers, keep
    ``contact_damping_ratio``. Why: at ``contact_damping_ratio`` a 1:1000 column struck from above
    at 8 iterations bounced for good, making energy even with its springs and preloads frozen (a
    preloaded row below its preload is rigid, and its update lags the column's heavy, slow mode); at
    25-40 it comes back to rest within the case's criteria, and a cold 1:1000 column no longer leaves
    the ground at 30 iterations (docs/method-notes.md, "A struck column at 8 iterations: the light
    rows' damping"). Higher pushes out more slowly: from ~60 the struck column sinks deeper (21 mm
    at 60, 42 mm at 100, criterion 20). Raising every row's damping instead costs the 1 mm cubes, the
    arch and the deep overlap (same section). A scene without such a pair never reads it."""

    contact_deflection: float = 0.002
    """[1] Largest static deflection a contact should show under its load, as a fraction
    of the smaller shape's bounding radius: a contact that holds up a body whose support
    force F (with what it carries, shared among its support points) would press it further
    at ``contact_hertz`` gets a stiffer spring, omega^2 = F K / (this x radius), up to the
    stability limit (solvers/contact_spring.py), and where the limit stops it the preload
    (``contact_preload``) carries the rest. Without it a spring follows the lighter body's
    mass, so a 1000 kg box on a 1 kg box sank ~30 cm, and not size, so 1 mm cubes sank
    ~0.8 mm. 0.002 (1.7 mm of a unit cube's 0.87 m radius): the 210-box pyramid's top sinks
    35 mm at 15 iterations with every solver, and 48 mm at 4 with mass splitting; at 0.001 the
    preload took so much of a pyramid's load at 15 iterations that mass splitting was still
    creeping after 10 s (resting KE 3.5e-5 J, only 2.8x below shuffled parallel PGS: the
    comparison the sandbox exists for), at 0.005 (before the preload) a pyramid's bottom row
    deflected ~3 mm. 0 turns load stiffening and the preload off."""

    contact_load_time: float = 0.25
    """[s] Time constant of the support-force average that ``contact_deflection`` reads, so
    that a bounce or an impact does not stiffen the spring it is acting through. Longer
    reacts more slowly to a new load (a heavy body landing sinks further first)."""

    contact_preload: float = 1.0
    """[1] Share of a contact's load beyond what its spring holds within ``contact_deflection``
    that it carries as a preload: impulse up to the preload is rigid, only what goes beyond it
    is soft (solvers/contact_spring.py). Why: the stability limit caps a few-iteration split
    schedule's spring far below what holds a tall pile within that deflection (the 210-box
    pyramid's top sank 0.32 m with mass splitting at 4 iterations); the preload carries the rest
    of the load without a stiffer spring, so the limit keeps the dynamics stable and the pile
    does not sag by the spring's measure. 0 turns it off (the spring alone)."""

    contact_preload_lag: float = 16.0
    """[1] How slowly the preload follows its load: the support-force average it reads has a time
    constant of this many 1 / omega_b, omega_b = sqrt(k / M) the rate at which the body bounces on
    its support springs (k their summed stiffness, M the mass they hold up), and never less than
    ``contact_load_time``. The preload integrates what the spring carries, so it must be slower
    than that bounce: a light body under a heavy one bounces slowly (1 kg under 1110 kg on springs
    capped for the light body: ~2 rad/s), and the 1:1000 heavy-on-light column rocked up and down
    by 0.3 m at 15 iterations with a fixed 0.25 or 0.5 s; a fixed 1 s settled that column but left
    a resting block still settling after 5 s at 2 iterations (docs/method-notes.md)."""

    max_push_speed: float = 3.0
    """[m/s] Cap on the separation speed the position bias may request, so a
    deep penetration separates without an explosion (Box2D v3 uses 3 m/s)."""

    overlap_push_speed: float = 1.0
    """[m/s] Cap on the push-out of a pair found overlapping when one of its bodies is put in the
    world (by the scene, an edit, a drop, a fracture's pieces): deeper than its slop plus twice
    ``contact_deflection`` x its bound, until it is out to that depth (manifold_cache.py; an
    impact between bodies already there arrives as a speculative gap and is never one; PhysX's
    per-body maximum depenetration velocity serves the same end). Both formulations.
    Such a push is no physics to keep, but the Jacobi family's split relax sweep takes it back
    only in part, so its momentum survives: ten boxes placed 30 % into each other rose at 5.4 m/s
    under mass splitting at 15 iterations with only ``max_push_speed``, 2.0 m/s with this
    (docs/method-notes.md). Above ``max_push_speed`` it changes nothing."""

    relax_push_speed: float = 0.0
    """[m/s] When > 0: a substep in which a contact's position bias asks for a push-out faster
    than this runs one relax sweep more (``sweeps`` + 1) under the Jacobi family (projected
    Jacobi, mass splitting, block mass splitting), whose split relax sweep takes a push back more
    slowly than Gauss-Seidel's. Ten boxes placed 30 % into each other rose at 5.4 m/s under mass
    splitting at 15 iterations, 3.5 m/s at 1 m/s here, before ``overlap_push_speed`` (which
    holds them to 2.0 m/s at no cost) existed (docs/method-notes.md, "Limits"). Off (0)
    by default: at 1 m/s a falling 1000-box pile's stiffened rows ask for such pushes in up to 9
    of 15 substeps, ~20 % more iteration-loop work while it falls. The push is capped at
    ``max_push_speed``, so a value at or above that never fires. Ignored under the paper
    formulation (no relax sweeps)."""

    restitution_threshold: float = 1.0
    """[m/s] Approach speed below which restitution is ignored, so resting
    contacts do not bounce forever; a contact closing faster (and touching within the step) is
    an impact, whose warm start carries only what stops its approach (impact_carry.clamp_impact_carry).
    Resting and stacked contacts must stay below it, hence > 0."""

    restitution_tolerance: float = 1e-3
    """[m/s] The restitution pass repeats its sweep until no bouncing contact's normal
    speed is further than this from -e times its approach speed, so that every schedule
    gives the same bounce (a single Jacobi-type sweep gave a 5 m/s cube 0.7 m/s back).
    Larger stops sooner with a bounce that much short or long."""

    warm_start: float = 1.0
    """[1] Fraction of last step's matched impulses applied before iterating.
    1 makes resting piles stiff across frames; 0 disables warm starting."""

    match_distance: float = 0.05
    """[m] A new contact point inherits the impulse of an old point of the same
    shape pair with the same feature id, or else of the nearest old point within
    this distance (clipping may rotate feature ids between frames)."""

    manifold_reuse_distance: float = 0.001
    """[m] A shape pair whose relative position moved less than this since its manifold
    was found, and turned less than ``manifold_reuse_angle``, keeps that manifold (its
    points ride with the bodies and their depths are measured again; manifold_cache.py)
    instead of running SAT and clipping again. What it skips is only new points
    appearing, which needs more relative motion. On a settled pile almost every pair is
    reused, which cuts the narrowphase to about a third (docs/bench.md, "Fifth pass");
    0 turns reuse off (Jolt's body pair cache uses 1 mm and 2 degrees)."""

    pair_reuse_margin: float = 0.02
    """[m] A dynamic shape enters the broadphase with its bounds grown by this much more (at
    most a quarter of its bounding radius): while its bounds stay inside those, and no partner's
    left theirs, it keeps its pairs instead of searching the grid again (pair_search.py; Box2D's
    and Rapier's enlarged bounds; in a step where more than a third of the shapes leave theirs,
    every shape searches, which lists the same pairs). Larger keeps pairs longer and lists more pairs that have no
    points. Each shape's partners are listed by id whatever it is, so the contacts do not
    depend on it, but for one thing: a pair kept without points skips the narrowphase while a
    bound says it cannot touch (manifold_cache.py), where a pair new to the list runs it, and
    the two can differ in far speculative points (docs/bench.md, "Fifteenth pass"). 0: a shape
    searches again whenever its bounds change at all."""

    manifold_reuse_angle: float = 0.001
    """[rad] The relative rotation bound of that reuse (at most pi). The kept points are
    where the clipping put them: at 0.01 rad serial PGS at 4 iterations let the card house
    of scenes/leaning_planks.toml fall (1.6 m, against 0.6 mm without reuse); at 0.001 rad
    it stands as without reuse, and a settled pile reuses as many manifolds (2263 of 2268
    after 400 steps of pile_1000)."""

    formulation: str = "soft-step"
    """How a step turns ``iterations`` into time stepping (sandbox/formulation.py).
    ``"soft-step"``: every iteration is a substep of Box2D v3's soft step (soft contact
    springs, a biased and a rigid relax sweep): the default, and what every figure in the
    docs uses unless it says otherwise. ``"paper"``: the scheme of Tonge et al. 2012 and
    of the talk's slides: one velocity-level solve per step, ``iterations`` sweeps with
    accumulated impulse clamping and warm starting, rigid rows with Baumgarte position
    correction (``baumgarte``), positions integrated with the biased velocities. The
    paper's scheme is where the jitter of parallel PGS shows; it gains energy on hard
    impacts and deep overlaps, which is why the soft step exists. Scene key:
    ``[world] formulation``."""

    baumgarte: float = 0.8
    """[1] Under ``formulation = "paper"``: the fraction of the penetration beyond ``slop``
    that the velocity solve asks to remove within one step (bias velocity gamma x depth / dt,
    capped at ``max_push_speed``, or ``overlap_push_speed`` for a placed overlap); the slides
    use 0.8. Higher corrects faster and pumps more energy into resting stacks; 0 leaves
    overlaps alone. Scene key: ``[world] baumgarte``."""

    sweeps: int = 1
    """[1] Sweeps of the solver per substep, for the biased solve and for the relax
    alike. One iteration = one substep with one sweep each is Box2D v3's soft
    step and the default; tests that need a single velocity-level problem solved
    to convergence use iterations = 1 with many sweeps. At few iterations every schedule
    sweeps more often (``step_sweeps``)."""

    iteration_launch: str = "auto"
    """How the iteration loop is launched (solvers/substep.py); the physics is the same bit
    for bit. ``"shared"``: all iterations in one kernel launch whose phases the CPU threads
    share, meeting at the end of each (solvers/team.py; serial ``pgs`` runs ``"one"``);
    ``"one"``: all iterations in one launch, run in order on one thread; ``"per-substep"``:
    one launch per iteration whose phases each run in parallel (not for ``pgs-colored``,
    which then goes stage by stage); ``"per-stage"``: one launch per phase, as the profiler
    times them; ``"auto"``: on the CPU ``"one"`` in a world of at most 64 bodies and ``"shared"``
    in larger ones (launch overhead, not arithmetic, bounds our scenes: a thread-pool wake-up per
    phase would cost more than the phase, and a few dozen bodies do not pay for the shared loop's
    barriers; schedule.ONE_THREAD_BODY_LIMIT), ``"per-substep"`` on CUDA. A world with its profiler on, or recording residuals, always
    goes stage by stage."""

    split_relaxation: float = 1.8
    """[1] Relaxation omega of per-point mass splitting: each split response is divided by it
    (over-relaxation; never below one sub-body, mass_splitting.py). The convergence proof of
    mass splitting holds for 0 < omega < 2 (method.md 1.7), and per-point splitting counts
    every corner of a face as a sub-body although the four corners lift a body together
    and turn it apart, so it steps short; 1.8 steps further without overshooting: on the
    210-box pyramid at 4 iterations the sag fell from 0.49 m to 0.28 m, at 15 iterations
    the resting energy from 1.4e-8 to 5.6e-10 J (docs/method-notes.md). Block mass
    splitting stays at 1: its manifolds rarely push a body one way (measured: over-relaxed,
    its friction arch collapsed). The ``relaxation`` solver option overrides both; 1 is the
    paper's plain average."""

    idle_split: float = 0.1
    """[1] Share of a split body kept for its blocks not counted in n_b (mass_splitting.py: a
    gap that did not look like closing this step), so that one that acts anyway cannot break the
    convergence proof's B >= A (method.md 1.7): with idle blocks the counted ones scale by
    n_b / (1 - share), the idle ones by n_idle / share (weighted Cauchy-Schwarz: the shares sum
    to one). Why: a body wedged between terrain triangles was pushed by one into another whose
    gap had not been counted, and the split diverged (mixed_on_terrain, step 40: 7.9e4 m/s).
    Higher makes idle rows step more and counted ones less (more sag); bodies without idle
    blocks are unaffected."""

    jacobi_relaxation: float = 0.25
    """[1] The largest relaxation factor omega projected Jacobi takes. Plain Jacobi (1.0)
    overshoots by the number of rows coupled through a body; stacks need omega ~ 1/n to
    survive, which makes them soft and slow to converge. Each step the ``jacobi`` solver takes
    the smaller of this and ``split_relaxation`` over its busiest body's block count (the split
    mass splitting would give that body, mass_splitting.py): 0.25 alone threw the card house
    (up to 40 points on a plank) apart at every iteration count. A ``relaxation`` solver option
    is taken as given instead."""

    fracture_min_piece_size: float = 0.01
    """[m] Smallest piece a Voronoi fracture may make, measured as the cube root of its
    volume. A body that would give smaller pieces stays whole: ``World.fracture`` raises,
    and a breakable body stops being breakable. Lower allows finer debris, which the
    per-pair margin and slop caps (a quarter and 2 % of the smaller shape) still
    handle, but every piece is one more body for the solver."""

    sleep_linear_speed: float = 0.05
    """[m/s] With the ``sleeping`` effect, a body counts as resting while its speed stays below
    this (and its angular speed below ``sleep_angular_speed``); an island whose bodies all rest
    for ``sleep_time`` goes to sleep (sleep.py). Box2D uses 0.05 m/s. Higher puts piles to sleep
    sooner but can freeze a slow slide or topple; lower keeps jittering bodies awake longer."""

    sleep_angular_speed: float = math.radians(2.0)
    """[rad/s] The angular speed below which a body counts as resting (2 deg/s, Box2D's value).
    A slowly tipping tall body turns at about this rate just before it falls, so much higher
    values would freeze topples."""

    sleep_time: float = 0.5
    """[s] How long every body of an island must rest before the island sleeps (Box2D: 0.5 s).
    Shorter sleeps sooner; too short catches bodies at the top of a bounce or a swing."""

    max_bodies: int = 1_000_000
    """[1] Most bodies a world may hold. Adding bodies or fracturing past it raises
    CapacityError naming this setting. Below it, buffers grow in powers of two as bodies
    arrive, keeping every body's state (each new size class compiles the kernels once)."""

    def __post_init__(self):
        check_settings(self)  # domains.DOMAINS: what each setting takes

    def manifold_reuse_bounds(self) -> tuple[float, float]:
        """(squared distance, sine of the half angle) the narrowphase compares against;
        (-1, -1) when reuse is off, which no pair passes."""
        if self.manifold_reuse_distance <= 0.0 or self.manifold_reuse_angle <= 0.0:
            return -1.0, -1.0
        return self.manifold_reuse_distance ** 2, math.sin(0.5 * self.manifold_reuse_angle)

    def replace(self, **changes) -> "Settings":
        """A copy with ``changes``; a setting's former name (RENAMED) still reads, so recordings and
        scripts made before a rename replay."""
        changes = {RENAMED.get(name, name): value for name, value in changes.items()}
        known = {f.name for f in fields(self)}
        unknown = set(changes) - known
        if unknown:
            raise SandboxError(f"unknown setting(s): {', '.join(sorted(unknown))}; known: {', '.join(sorted(known))}")
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return Settings(**values)
