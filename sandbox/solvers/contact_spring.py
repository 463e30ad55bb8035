"""The soft contact's spring, row by row: how stiff each contact is, and why no stiffer.

Box2D v3's soft step (solvers/rows.py) turns a penetration beyond the slop into a
spring-damper of angular frequency omega and damping ratio zeta: with the substep h and
c = h omega (2 zeta + h omega) the normal row solves ``n . v + b + gamma lambda >= 0`` with
bias ``b = rate x penetration``, ``rate = omega / (2 zeta + h omega)`` and compliance
``gamma = K / c`` (K the row's unsplit unit response). A contact carrying a force F
deflects ``F K / omega^2`` at rest.

Three things set a row's omega, in this order (and a fourth, the preload, carries what the
third leaves of the load; a fifth, the rocking share, gives back to a face's tilt what the third
took):

1. ``Settings.contact_hertz``, the softness asked for (capped at a quarter of the substep
   rate, as Box2D does);
2. its load: a contact whose load F would press it further than ``contact_deflection``
   x its pair's size gets omega^2 = F K / that deflection, so that a heavy body on a light
   one, or a stack of millimetre cubes, does not sink by the light body's or the small
   body's measure. F is not the contact's own impulse: a stiffness that follows its own
   force makes a body resting on two supports send ever more load to the stiffer one (a
   statically indeterminate load split with stiffness growing with load has no stable
   equilibrium; measured: a resting pyramid's energy 1e-8 J -> 1.6 J). F is the support
   force of the body the contact holds up (the upward component of all its support
   impulses, averaged over ``contact_load_time``) shared equally among that body's support
   points (``mass_splitting.update_support``): what the body weighs, with what it carries;
3. the stability limit of the schedule: ``omega h <= kappa sqrt(S K / K~)``, S the sweeps the row
   gets per substep (a light body's rows, swept again under the Jacobi family, count their extra
   sweeps under mass splitting and Jacobi: LIGHT_LIMIT; those rows are also damped more,
   Settings.light_damping_ratio).

Why the limit (docs/method-notes.md, "Why low iteration counts blew up"): a sweep steps a
row by ``dl = -(J v + b + gamma lambda) / (K~ + gamma)``, where K~ is the response the
schedule divides by (K for PGS; ~n_b K for mass splitting, whose n_b sub-bodies each see
1/n_b of the body). The spring's damping acts through that update, and for the slow,
whole-structure modes of a stack the update only forgets a fraction gamma / K~ of the old
impulse per sweep: the spring force lags. A third-order model of one such mode (impulse,
velocity, penetration) is stable while ``gamma S / (K~ h) > rate`` (S sweeps per substep),
i.e. while ``(h omega)^2 < S K / K~`` to first order, whatever zeta is. Measured on the
210-box pyramid the onset is at kappa ~0.7 for PGS, mass splitting and block mass
splitting alike (mass splitting at 4, 8 and 15 iterations, PGS at 2, 4 and 8).
The same inequality bounds every stable row's static deflection from below:
``F K / omega^2 >= F K~ h^2 / (S kappa^2)``. A schedule that divides by a larger K~ (mass
splitting) would sag more at the same substep (the 210-box pyramid's top sank 0.32 m with
mass splitting at 4 iterations), hence the preload.

The preload: what a capped spring cannot hold within ``contact_deflection`` x size, the row
carries rigidly. It solves ``J v + b + gamma max(lambda - P, 0) >= 0``: impulse up to the
preload P is a rigid row's, only the impulse beyond it meets the compliance. P is the
point's load beyond the spring's force at that deflection, ``F_slow - omega^2 d / K``, per
substep, with ``F_slow`` the support force averaged more slowly (``contact_preload_lag``).
The dynamics keep the capped spring (the update of an impulse beyond P is the soft row's, so
the stability limit still holds); the statics do not sag by it: at rest every loaded row sits
at the deflection, a few millimetres. P follows a slow average because it integrates what the
spring carries, and an integrator faster than the structure it holds makes it bounce: with the
spring's 0.25 s average the 1:1000 heavy-on-light column rocked by 0.3 m at 15 iterations
(docs/method-notes.md), so the average follows no faster than the body bounces on its support
springs, divided by ``contact_preload_lag``. It reads the body's support shared equally among
its support points, never the row's own impulse (the load-split argument above; a preload that
followed each point's own warm start threw the pyramid apart).

The rocking share: the preload holds a face's load, not its tilt, so a capped spring is also a
soft hinge, and a tall column on soft hinges buckles under its own weight (P-Delta) however
stable the solve: a 20-box column needs omega >= ~270 rad/s, mass splitting at 8 iterations may
carry 193. A capped row therefore reads, for its push-out, its depth beyond its manifold's mean
depth up to ``rocking`` times over (rocking_share, normal_target.bias_push): a face keeps the capped
spring in compression and resists turning up to 1 + ``Settings.contact_rocking_stiffness`` times
as stiffly (docs/method-notes.md, "The nudged column at 8 iterations").
"""

import math

import taichi as ti

from ..formulation import PAPER, baumgarte_rate
from ..math3d import dot

(INV_H, OMEGA, ZETA, STIFFNESS_LIMIT, MAX_PUSH, RESTITUTION_THRESHOLD, DEFLECTION, LOAD_BLEND, STEP_DT, UP_X, UP_Y,
 UP_Z, GRAVITY_REACH, BAUMGARTE_RATE, IDLE_SHARE, GRAVITY_X, GRAVITY_Y, GRAVITY_Z, PRELOAD, PRELOAD_LAG,
 RELAX_PUSH, OVERLAP_PUSH, SPLIT_BOUND, ROCKING, LIGHT_LIMIT, RATIO_MASS, RATIO_SWEEPS, LIGHT_ZETA) = range(28)
PARAM_COUNT = 28
"""Slots of ``Rows.params``: the substep rate [1/s], the asked-for omega [rad/s], zeta,
kappa sqrt(S) [1], the push-speed cap [m/s], the restitution threshold [m/s], the load
deflection [1], the support average's blend per step [1], the step [s], the up
direction (against gravity; zero without gravity), the gap gravity closes in one step
from rest, |g| dt^2 [m], and the paper formulation's Baumgarte rate [1/s] (0: the soft step;
formulation.py), the split's share kept for blocks not counted in n_b (Settings.idle_split),
gravity [m/s^2] (read by the iteration loop's fused launches, solvers/substep.py), the preload's
share [1] and its lag [1] (Settings.contact_preload, contact_preload_lag), and the push speed
that earns a substep a second relax sweep [m/s] (Settings.relax_push_speed; 0: never, and under
the paper formulation, which has no relax sweeps), the push-out cap of a pair found overlapping
[m/s] (Settings.overlap_push_speed), and the relaxation mass splitting's convergence bound takes
[1] (Settings.split_relaxation; 1, the paper's plain average, under the paper formulation), which
projected Jacobi's global factor takes for its busiest body (mass_splitting.py), and the most a
row's rocking stiffness may exceed its capped spring [1] (Settings.contact_rocking_stiffness), and
for the rows of a body resting against a far heavier one, their kappa sqrt(S) [1] with their extra
sweeps counted, the mass ratio that marks them [1] and their extra sweeps per substep [1]
(Settings.ratio_sweeps, ratio_mass; 0 sweeps: none this step, formulation.SweepPlan.ratio), and
their damping ratio [1] (Settings.light_damping_ratio)."""

SUPPORT_COS = 0.7071
"""A contact supports the body it pushes when its push is within 45 degrees of up."""



def row_params(settings, h: float, sweeps: int, dt: float, gravity, rocking: bool = True,
               ratio_sweeps: int = 0, light_stiffer: bool = True) -> list[float]:
    """This step's ``Rows.params`` values from ``settings`` for substeps of ``h`` [s] with
    ``sweeps`` biased and as many relax sweeps each, in steps of ``dt`` [s], under ``gravity``
    [m/s^2] (step.py writes them into ``Rows.params``); ``rocking``: the schedule stiffens a face's
    rocking (SolverInfo.stiffens_rocking); ``ratio_sweeps``: the biased sweeps more of the rows of a
    body resting against a far heavier one (formulation.SweepPlan.ratio), whose springs take the
    limit of the sweeps they get, ``sweeps`` biased + ``ratio_sweeps`` + ``sweeps`` relax, when
    ``light_stiffer`` (SolverInfo.stiffens_light_rows; docs/method-notes.md, "A kicked column:
    light rows stiffer than their sweeps")."""

    values = [0.0] * PARAM_COUNT
    values[INV_H] = 1.0 / h
    values[OMEGA] = 2.0 * math.pi * min(settings.contact_hertz, 0.25 / h)
    values[ZETA] = settings.contact_damping_ratio
    kappa = settings.contact_stiffness_limit
    values[STIFFNESS_LIMIT] = kappa * math.sqrt(2.0 * sweeps)
    values[MAX_PUSH] = settings.max_push_speed
    values[RESTITUTION_THRESHOLD] = settings.restitution_threshold
    values[DEFLECTION] = settings.contact_deflection
    values[LOAD_BLEND] = min(1.0, dt / settings.contact_load_time) if settings.contact_load_time > 0 else 1.0
    values[STEP_DT] = dt
    g = math.sqrt(sum(float(x) ** 2 for x in gravity))
    if g > 0.0:
        values[UP_X], values[UP_Y], values[UP_Z] = (-float(x) / g for x in gravity)
    values[GRAVITY_REACH] = g * dt * dt
    values[BAUMGARTE_RATE] = baumgarte_rate(settings, dt)
    values[IDLE_SHARE] = settings.idle_split
    values[GRAVITY_X], values[GRAVITY_Y], values[GRAVITY_Z] = (float(x) for x in gravity)
    values[PRELOAD] = settings.contact_preload
    values[PRELOAD_LAG] = settings.contact_preload_lag
    values[RELAX_PUSH] = relax_push_limit(settings)
    values[OVERLAP_PUSH] = settings.overlap_push_speed
    values[SPLIT_BOUND] = settings.split_relaxation if settings.formulation != PAPER else 1.0
    values[ROCKING] = settings.contact_rocking_stiffness if rocking else 0.0
    values[LIGHT_LIMIT] = kappa * math.sqrt(light_sweeps(sweeps, ratio_sweeps, light_stiffer))
    values[RATIO_MASS] = settings.ratio_mass
    values[RATIO_SWEEPS] = float(ratio_sweeps)
    values[LIGHT_ZETA] = settings.light_damping_ratio
    return values


def light_sweeps(sweeps: int, ratio_sweeps: int, light_stiffer: bool) -> int:
    """S of a light body's rows in the stability limit: the sweeps a substep gives them, ``sweeps``
    biased and as many relax, and ``ratio_sweeps`` more biased when the schedule stiffens them for
    those (``light_stiffer``). Until 2026-11-28 they took the limit of ``sweeps`` + 2 sweeps of each
    kind, kappa sqrt(6), with 2 extra sweeps, i.e. 4 per substep: stiffer than their sweeps can damp.
    The 1:1000 column held still, but struck it bounced for good at 15 iterations, making ~120 J
    (docs/method-notes.md)."""
    return 2 * sweeps + (ratio_sweeps if light_stiffer else 0)


def relax_push_limit(settings) -> float:
    """[m/s] The push speed that earns a Jacobi-family substep a second relax sweep
    (Settings.relax_push_speed), 0 when there is none: off, or the paper formulation, which has
    no relax sweeps."""
    return settings.relax_push_speed if settings.formulation != PAPER else 0.0


@ti.func
def params_gravity(rows: ti.template()) -> ti.math.vec3:
    """The step's gravity [m/s^2] from ``rows.params`` (row_params)."""
    return ti.math.vec3(rows.params[GRAVITY_X], rows.params[GRAVITY_Y], rows.params[GRAVITY_Z])


@ti.func
def row_omega(params: ti.template(), k_true: ti.f32, k_split: ti.f32, load: ti.f32, size: ti.f32, light: ti.i32):
    """(omega, the omega asked for before the stability limit) [rad/s] of a row with unsplit
    response ``k_true``, the schedule's ``k_split``, averaged normal force ``load`` [N] and pair
    size ``size`` [m] (module docstring); ``light`` = 1: a light body's row, swept more and
    limited for those sweeps (light_sweeps, Settings.ratio_sweeps)."""
    omega = params[OMEGA]
    deflection = params[DEFLECTION] * size
    if deflection > 0.0 and load > 0.0:
        omega = ti.max(omega, ti.sqrt(load * k_true / deflection))
    wanted = omega
    if params[STIFFNESS_LIMIT] > 0.0:
        limit = params[LIGHT_LIMIT] if light else params[STIFFNESS_LIMIT]
        omega = ti.min(omega, limit * ti.sqrt(k_true / k_split) * params[INV_H])
    return omega, wanted


@ti.func
def rocking_share(params: ti.template(), omega: ti.f32, wanted: ti.f32) -> ti.f32:
    """alpha [1]: a row's push-out reads its depth d as d + alpha (d - the mean depth of its
    manifold's touching points) (normal_target.bias_push), which leaves a face's compression on the capped
    spring and makes its rocking 1 + alpha times stiffer: up to the stiffness the limit took away,
    (wanted / omega)^2 - 1, and at most ``Settings.contact_rocking_stiffness``. 0 where the limit
    did not cap the row. Why a column needs it, and why not a higher limit instead: the
    setting's docstring."""
    share = 0.0
    if omega > 0.0 and wanted > omega:
        share = ti.min(params[ROCKING], (wanted / omega) ** 2 - 1.0)
    return share


@ti.func
def spring(params: ti.template(), omega: ti.f32, k_true: ti.f32, zeta: ti.f32):
    """(bias rate [1/s], compliance gamma) of a spring of ``omega`` and damping ratio ``zeta`` on a
    row of response ``k_true`` over one substep (Box2D v3 ``b2MakeSoft`` in the compliance form)."""
    h = 1.0 / params[INV_H]
    return omega / (2.0 * zeta + h * omega), k_true / (h * omega * (2.0 * zeta + h * omega))


@ti.func
def row_spring(params: ti.template(), k_true: ti.f32, k_split: ti.f32, load: ti.f32, slow_load: ti.f32,
               size: ti.f32, light: ti.i32):
    """(bias rate [1/s], compliance gamma, preload [N s], rocking share [1]) of a normal row: the
    soft step's spring with the preload that carries ``slow_load`` [N] beyond what the spring holds
    within the deflection and the face's rocking stiffness (rocking_share), or under the paper
    formulation a rigid row (gamma 0, no preload, no rocking share) whose bias removes
    ``baumgarte`` of the depth per step. ``light``: row_omega, and the spring takes the light rows'
    damping ratio (Settings.light_damping_ratio)."""
    rate = params[BAUMGARTE_RATE]
    gamma = 0.0
    preload = 0.0
    rocking = 0.0
    if rate <= 0.0:
        omega, wanted = row_omega(params, k_true, k_split, load, size, light)
        rate, gamma = spring(params, omega, k_true, params[LIGHT_ZETA] if light else params[ZETA])
        rocking = rocking_share(params, omega, wanted)
        if params[DEFLECTION] > 0.0:
            held = omega * omega * params[DEFLECTION] * size / k_true  # [N] the spring's force at the deflection
            preload = params[PRELOAD] * ti.max(slow_load - held, 0.0) / params[INV_H]
    return rate, gamma, preload, rocking


@ti.func
def support_push(params: ti.template(), push: ti.math.vec3) -> ti.f32:
    """How much a contact pushing its body along ``push`` holds it up: push . up when that is
    within 45 degrees of up, else 0."""
    u = dot(push, ti.math.vec3(params[UP_X], params[UP_Y], params[UP_Z]))
    return u if u >= SUPPORT_COS else 0.0


@ti.func
def supported_load(params: ti.template(), c: ti.template(), bodies: ti.template(), q: ti.i32):
    """([N], [N]) The load of point q: the averaged support force of the body it holds up,
    shared equally among that body's support points (0 when it holds up neither body), over
    ``contact_load_time`` (the spring's) and the slower one the preload reads."""
    n = c.normal[q]  # from body a to body b: b is pushed along +n
    upper = -1
    if support_push(params, n) > 0.0:
        upper = c.body_b[q]
    elif support_push(params, -n) > 0.0:
        upper = c.body_a[q]
    load = 0.0
    slow_load = 0.0
    if upper >= 0:
        if bodies.inv_mass[upper] > 0.0:
            points = ti.max(ti.cast(bodies.support_points[upper], ti.f32), 1.0)
            load = bodies.support[upper] / points
            slow_load = bodies.support_slow[upper] / points
    return load, slow_load
