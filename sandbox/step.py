"""The step: a fixed list of named, timed stages over one world's buffers.

The step, stage by stage (names = profile keys = report keys, profile.STAGES):

1. ``broadphase``   AABBs, hash grid, candidate pairs (broadphase.py, pair_search.py)
2. ``narrowphase``  manifolds into the contact buffer (contacts.py)
3. ``prepare``      rows, warm-start matching, schedule set-up (solvers/)
4. ``iterations`` substeps of h / iterations (Box2D v3's soft step, see solvers/rows.py):
   ``integrate_velocities`` (gravity), ``iterate`` (warm start + one biased sweep of the
   chosen schedule; more of each kind below 8 iterations,
   Settings.step_sweeps), ``integrate_positions`` (symplectic Euler, conservative rotation),
   ``relax`` (one rigid sweep without position bias; two after a fast push
   under the Jacobi family when ``Settings.relax_push_speed`` asks for it)
5. ``relax``        restitution pass (repeated until the bounce converges, for every schedule),
   impulses stored for the next step

Under ``Settings.formulation = "paper"`` step 4 is one substep of h with ``iterations``
biased sweeps of rigid Baumgarte rows and no relax sweep (formulation.py).

Python only orchestrates. With the profiler off, the once-per-step stages run in three
launches (``step_kernels.py``: state save + broadphase + narrowphase, then rows + matching +
schedule set-up, then the bodies' finite check + contact store; the same loops as the per-stage
kernels, the same bits). The iteration loop of step 4 is one kernel launch on the CPU,
shared by its threads (``Settings.iteration_launch``, solvers/substep.py and team.py:
launch and dispatch overhead, not arithmetic, bound small scenes), and where nothing runs
on the host mid-step the set-up, that loop and the store are one launch
(``step_kernels.solve_step_in_order`` / ``solve_step_shared``: two launches a step); on CUDA
the loop is one launch per substep; with the profiler on it runs stage by stage, a launch per phase, so that
each stage has its timer (the unfused path; the iteration loop is then ``iterate`` plus the
per-phase stages), unless the profiler times launch by launch (profile.py: the fused launches,
each timed under its stage group's name). Which kernels a sweep launches is the schedule's business
(solvers/schedule.py); this module only orders the stages.

Besides the launches a step makes two small reads: buffer counters after the narrowphase
(a buffer that overflowed is grown and the step redone from the saved state) and the error
bits at the end (non-finite state: the last good state is restored and a SimulationError
names the body and the stage). ``[world] substeps`` repeats the whole step, collision
included, with dt / substeps (``World.step`` calls ``Stepper.substep`` that many times).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np
import taichi as ti

from . import step_kernels
from .bodies import restore_good_state, save_good_state, update_world_inertia
from .broadphase import speculation
from .effects import CompiledEffects
from .errors import CapacityError, SimulationError
from .field_upload import write_rows
from .integrate import check_bodies, motion_switch
from .manifold_cache import overlap_depth
from .persistence import match_contacts, store_contacts
from .sleep import after_step, wake_touched
from .solvers.contact_spring import relax_push_limit, row_params
from .solvers.mass_splitting import update_support
from .solvers.rows import contact_switch, prepare_rows
from .solvers.schedule import Loop, Schedule
from .solvers.substep import BLOCKS
from .step_scalars import step_scalar_values

MAX_GROWTH_RETRIES = 6
RESTITUTION_MAX_SWEEPS = 256
"""[1] Most restitution sweeps a step may run: projected Jacobi (relaxation 0.25) needs ~50 to
bring a 5 m/s bounce within ``Settings.restitution_tolerance``, more where its busiest body's
split is larger (a split of s shrinks a lone box's error by ~(1 - 4 / s) a sweep); past this the
bounce stays short."""


@dataclass(frozen=True)
class Controls:
    """What the world's setters chose, read by every substep of one step."""

    schedule: Schedule
    iterations: int  # substeps of the soft step, one sweep each by default (Schedule.plan)
    gravity: np.ndarray  # [m/s^2], shape (3,), float32
    effects: CompiledEffects  # compile-time switches (effects.py)
    track_impulses: bool  # each substep's impulses summed into the step's (World.track_impulses)
    record_residuals: bool  # a residual read after every biased sweep (forces the staged path)
    loop_arch: str  # whose loop shapes the step takes (backend.loop_arch): picks the iteration launch


@dataclass(frozen=True)
class Sweep:
    """Where a paused step stands: after sweep ``index`` of ``count`` of the ``phase``
    ("biased", "extra biased": the Jacobi family's sweeps of light bodies' blocks,
    Settings.ratio_sweeps, or "relax") of substep ``substep`` of ``substeps``. ``carries_warm_start``: this
    relax sweep also applied the next substep's gravity and warm start (the Jacobi family)."""

    substep: int
    substeps: int
    phase: str
    index: int
    count: int
    carries_warm_start: bool


class Stepper:
    """Runs substeps over ``edits``' buffers (edits.py: they may be replaced by a growth)."""

    def __init__(self, edits, profiler):
        self.edits = edits
        self.profiler = profiler
        self.fused = True  # False: the once-per-step stages launch one by one (benchmarks compare)
        self.residual_history: list[float] = []
        self._constants_key = None

    def substep(self, c: Controls, h: float, watch: bool, first: bool, step_count: int) -> None:
        """One pass of the whole stage list with time step ``h`` [s]; ``watch``: breakable bodies'
        impulses are monitored (``first``: the step's first substep clears their peaks). In a
        sleeping world whose last step had no awake body, and nothing woke since, it does
        nothing: that step would change no bit (sleep.SleepBuffers.idle)."""
        for _ in self.substep_sweeps(c, h, watch, first, step_count, pause=False):
            pass

    def substep_sweeps(self, c: Controls, h: float, watch: bool, first: bool, step_count: int, pause: bool):
        """``substep`` as a generator. With ``pause`` the iteration loop runs stage by stage (the
        same bits) and stops after every sweep, yielding a ``Sweep`` (inspection.py looks inside
        the solve there); without, it yields nothing."""
        if c.effects.sleeping and self.edits.buf.sleep.idle:
            return
        b, s, p = self.edits.buf, self.edits.settings, self.profiler
        # the light bodies' sweeps leave a GPU's launch only: on the CPU their empty loops cost
        # nothing and a second set of iteration kernels costs compiling (effects.py)
        plan = c.schedule.plan(s, c.iterations, c.effects.light_bodies or c.loop_arch == "cpu")
        # the once-per-step stages in three launches, or two (step_kernels.py); a profiler timing
        # stage by stage launches them one by one, one timing launch by launch keeps them (profile.py)
        fused = self.fused and not (p.enabled and p.per_stage)
        if not fused:
            awake = self.edits.awake_set(c.effects.sleeping)
            save_good_state(b.bodies, awake)
            b.errors.clear()
            update_world_inertia(b.bodies, awake)
        self.residual_history = []
        with p.stage("collide") if fused else contextlib.nullcontext():  # fused: one launch, or a retry
            b = self._collide_growing(fused, h, c, plan)
        awake = self.edits.awake_set(c.effects.sleeping)  # the buffers may have grown
        if watch and first:
            from .impact import clear_bodies

            clear_bodies(b.impacts, b.bodies)
        bounce = c.effects.restitution
        track = watch or bounce or c.track_impulses  # the restitution pass reads which points carried load
        staged = (p.enabled and p.per_stage) or c.record_residuals or pause  # a timer per stage, a read per sweep
        launch = "per-stage" if staged else c.schedule.launch(s, c.loop_arch, b.caps.bodies, plan)
        friction = contact_switch(c.effects)
        if fused and launch in ("one", "shared") and not (watch or bounce or c.schedule.info.needs_coloring):
            # nothing for the host between set-up, solve and store: one launch, the same bits
            sc = c.schedule
            switches = step_kernels.solve_switches(sc.kind, sc.mode, sc.info.scales_masses, friction, sc.visit,
                                                   s.warm_start > 0.0, track, motion_switch(c.effects))
            with p.stage("solve"):
                if launch == "one":
                    step_kernels.solve_step_in_order(b, switches, awake, self.edits.dispatch)
                else:
                    crew = sc.team(b, plan.substeps, plan.biased, plan.relax, plan.ratio)
                    step_kernels.solve_step_shared(b, switches, *crew, awake, self.edits.dispatch)
        else:
            yield from self._solve_in_launches(c, b, awake, plan, h, launch, fused, watch, track, step_count, pause)
        self._check_errors(b, step_count)
        self.edits.placed_seen()
        if c.effects.sleeping:
            after_step(b, h, s, labelled=fused)

    def _solve_in_launches(self, c: Controls, b, awake, plan, h: float, launch: str, fused: bool, watch: bool,
                           track: bool, step_count: int, pause: bool):
        """Set-up, iteration loop and store as separate launches: the fused set-up and store
        around one of the schedule's loop launches, or every stage timed (profiler, residual
        record) or stopped after every sweep (``pause``: a generator, as ``substep_sweeps``)."""
        s, p = self.edits.settings, self.profiler
        k = plan.substeps
        friction = contact_switch(c.effects)
        loop = Loop(b, friction, s.warm_start > 0.0, track, ti.math.vec3(*c.gravity), h / k, k, plan.biased,
                    plan.relax, awake, motion_switch(c.effects), plan.ratio)
        with p.stage("prepare"):
            if fused:
                sc = c.schedule
                step_kernels.prepare_step(b, sc.kind, sc.mode, sc.info.scales_masses, friction, self.edits.dispatch)
                c.schedule.color(b, step_count)
            else:
                prepare_rows(b.rows, b.contacts, b.bodies)
                match_contacts(b.history, b.contacts, b.rows, s.match_distance, s.warm_start / k)
                c.schedule.prepare(b, s, step_count, friction)
        if launch == "per-stage":
            yield from self._iterate_by_stage(c.schedule, loop, c.record_residuals, pause)
        else:
            with p.stage("iterate"):
                c.schedule.iterate(launch, loop)
        if watch:
            from .impact import reduce_manifolds

            reduce_manifolds(b.impacts, b.contacts, b.rows)
        with p.stage("relax"):
            if c.effects.restitution:
                c.schedule.restitution(b, awake, friction, s.restitution_tolerance, RESTITUTION_MAX_SWEEPS)
            if fused:
                step_kernels.finish_step(b, c.schedule.kind, awake, self.edits.dispatch)
            else:
                check_bodies(b.bodies, b.errors, awake)
                update_support(b.blocks, b.contacts, b.rows, b.bodies, awake, c.schedule.kind, self.edits.dispatch)
                store_contacts(b.history, b.contacts, b.rows, b.shapes, k, awake, self.edits.dispatch)

    def _write_step_constants(self, b, s, c: Controls, h: float, plan) -> None:
        """This step's row constants (contact_spring.row_params, in ``rows.params``) and the fused
        kernels' scalars (step_scalars.py) into ``b``, worked out and written, in one launch, only
        when the buffers, the settings, the solver or the step's shape changed (~10 us of a 150 us
        small step; as kernel arguments they cost ~0.1 ms of Python per step, and as three
        ``from_numpy`` calls three kernel instances to load at a world's first step)."""
        key = (b, s, c.schedule, h, plan, *c.gravity)
        if key != self._constants_key:
            info = c.schedule.info
            params = row_params(s, h / plan.substeps, plan.biased, h, c.gravity, info.stiffens_rocking, plan.ratio,
                                info.stiffens_light_rows)
            floats, ints = step_scalar_values(s, c.schedule.relaxation(s), h, plan)
            write_rows([(b.rows.params, 0, np.asarray(params)), (b.scalars.f, 0, np.asarray(floats)),
                        (b.scalars.i, 0, np.asarray(ints))])
            self._constants_key = key

    def _collide_growing(self, fused: bool, h: float, c: Controls, plan):
        """Broadphase and narrowphase; an overflowing buffer is grown and the collision redone
        (a fused retry saves the restored, same, state again and redoes the inertias: same bits).
        In a sleeping world, a touched sleeping island is woken and the collision redone with
        it awake (sleep.wake_touched): each redo wakes at least one island, so it ends."""
        growths = 0
        sleeping = c.effects.sleeping
        while True:
            b, st = self.edits.buf, self.edits.settings
            self._write_step_constants(b, st, c, h, plan)  # also into buffers just grown
            awake = self.edits.awake_set(sleeping)
            if fused:
                step_kernels.begin_and_collide(b, speculation(st), self.edits.kinds, awake, self.edits.dispatch)
            else:
                self._collide(h, awake)
            if self.edits.grow_if_needed():
                growths += 1
                if growths > MAX_GROWTH_RETRIES:
                    raise CapacityError("contact buffers kept overflowing after growing; the scene is too dense")
            elif not (sleeping and wake_touched(b, st.contact_margin)):
                return b

    def _collide(self, h: float, awake) -> None:
        from .broadphase import build_dynamic_grid
        from .contacts import collide_pairs
        from .pair_search import find_pairs

        b, p, st = self.edits.buf, self.profiler, self.edits.settings
        margin = st.contact_margin
        with p.stage("broadphase"):
            build_dynamic_grid(b.bp, b.shapes, b.bodies, margin, st.pair_reuse_margin, h, speculation(st), b.errors,
                               awake, self.edits.dispatch)
            find_pairs(b.bp, b.shapes, awake, self.edits.dispatch)
        with p.stage("narrowphase"):
            collide_pairs(b.contacts, b.bp, b.shapes, b.bodies, b.pool, b.manifold_cache, margin, st.slop,
                          overlap_depth(st), h, speculation(st), *st.manifold_reuse_bounds(), self.edits.kinds, awake,
                          self.edits.dispatch)

    def _iterate_by_stage(self, schedule: Schedule, loop: Loop, record_residuals: bool, pause: bool):
        """The iteration loop a launch per phase, each in its stage. With warm starting, gravity
        rides on the warm-start pass ("iterate"), and for the Jacobi family both ride on the
        previous substep's last relax sweep (its impact rows' carries clamped after it). A generator:
        with ``pause`` it yields a ``Sweep`` after every sweep."""
        from .integrate import integrate_positions, integrate_velocities
        from .solvers.mass_splitting import clamp_folded_carries_kernel
        from .solvers.rows import BIASED, RELAX
        from .solvers.step_impulses import add_step_impulses

        b, p, k, sweeps, relax, awake = loop.buf, self.profiler, loop.iterations, loop.sweeps, loop.relax, loop.awake
        extra = int(b.blocks.light_sweeps[None]) if loop.ratio else 0  # light bodies' (Settings.ratio_sweeps)
        fold = schedule.folds_warm_start(loop.warm)
        # the Jacobi family with Settings.relax_push_speed on: a fast push earns a second relax sweep,
        # which the host learns from a flag read per substep
        watch_push = schedule.visit == BLOCKS and relax_push_limit(self.edits.settings) > 0.0
        for i in range(k):
            if i == 0 or not fold:
                if loop.warm:
                    with p.stage("iterate"):
                        schedule.warm_start(b, awake, loop.friction, loop.gravity, loop.h)
                else:
                    with p.stage("integrate_velocities"):
                        integrate_velocities(b.bodies, awake, loop.gravity, loop.h)
            with p.stage("iterate"):
                if watch_push:
                    b.rows.fast_push[None] = 0
                for j in range(sweeps):
                    schedule.sweep(b, awake, BIASED, loop.friction, substep=i)
                    if record_residuals:
                        self.residual_history.append(residual_rms(b, BIASED))
                    if pause:
                        yield Sweep(i, k, "biased", j, sweeps, False)
                for j in range(extra):
                    schedule.sweep(b, awake, BIASED, loop.friction, substep=i, light_only=1)
                    if record_residuals:
                        self.residual_history.append(residual_rms(b, BIASED))
                    if pause:
                        yield Sweep(i, k, "extra biased", j, extra, False)
            with p.stage("integrate_positions"):
                integrate_positions(b.bodies, awake, loop.motion, loop.h)
            with p.stage("relax"):
                n_relax = relax + (int(b.rows.fast_push[None]) if watch_push else 0)
                for j in range(n_relax):
                    then_warm = int(fold and i < k - 1 and j == n_relax - 1)
                    schedule.sweep(b, awake, RELAX, loop.friction, then_warm, loop.gravity, loop.h, i)
                    if pause:
                        yield Sweep(i, k, "relax", j, n_relax, bool(then_warm))
                if fold and i < k - 1:  # the impact rows' carries, clamped after the carrying sweep's merge
                    clamp_folded_carries_kernel(b.rows, b.contacts, b.bodies, loop.friction)
            if loop.track:
                add_step_impulses(b.rows, b.contacts)

    def _check_errors(self, b, step_count: int) -> None:
        """The step's error bits as a SimulationError, the world back at its last good state."""
        flags = int(self.edits.counters.error_flags())
        if not flags:
            return
        from .broadphase import MAX_SPAN_CELLS
        from .integrate import ERR_POSE, ERR_VELOCITY
        from .manifold_cache import clear_cache
        from .persistence import clear_history

        body = int(b.errors.body[None])
        name = self.edits.body_name(body)
        if flags & (ERR_VELOCITY | ERR_POSE):
            stage = "solve (velocity)" if flags & ERR_VELOCITY else "integrate_positions (pose)"
            problem = f"non-finite {stage} of body {body}{name}"
        else:
            v = float(np.linalg.norm(b.bodies.lin_vel[body]))
            w = float(np.linalg.norm(b.bodies.ang_vel[body]))
            problem = (f"body {body}{name} reached |v| = {v:.3g} m/s, |w| = {w:.3g} rad/s: its bounds over the "
                       f"step cover more than {MAX_SPAN_CELLS} broadphase cells of {b.bp.cell_size[None]:.3g} m "
                       "(the solver diverged, or the body is far larger than the typical one)")
        restore_good_state(b.bodies)
        clear_history(b.history)  # this step's impulses are not usable either: no warm start from them
        self.edits.keep_overlaps()  # the overlaps being pushed out stay marked when the pairs are found again
        clear_cache(b.manifold_cache)  # nor its manifolds (a replay from the good state would not have them)
        raise SimulationError(f"step {step_count}: {problem}; the world was restored to its last good state")


def residual_rms(b, mode: int) -> float:
    """RMS residual [m/s] of the BIASED or RELAX problem (solvers/rows.py) right now."""
    from .metrics import RES_SQ_SUM, compute_metrics
    from .solvers.rows import compute_residuals

    compute_residuals(b.rows, b.contacts, b.bodies, mode)
    compute_metrics(b.metrics, b.bodies, b.contacts, b.rows)
    n = int(b.contacts.count[None])
    return float(np.sqrt(b.metrics.values[RES_SQ_SUM] / (3 * n))) if n else 0.0
