"""Mass splitting (Tonge et al. 2012, method.md 1.6 and 1.11): every contact block solved at
once on its own copies of its bodies, each body's impulses merged by a deterministic
scatter/gather. Projected Jacobi is the same schedule with one global split factor.

A *block* is either one contact point (``mass-splitting``, ``jacobi``) or one manifold,
i.e. all points of one shape pair (``block-mass-splitting``; also the unit the PGS
solvers visit). Each block has two endpoints (its bodies a and b). For every dynamic
body we build, per step, the sorted list of endpoints touching it (counting sort by
body, then a per-body sort, so thread timing never changes the order). A sweep writes
one velocity change per endpoint into its slot; each body then sums its slots in that
fixed order. No float atomics, so CPU runs are bitwise repeatable.

Per body, ``scale`` multiplies inverse mass and inertia inside a block and ``weight``
multiplies the velocity change written to the slot:
* mass splitting (``MODE_SPLIT``): scale = n_b, weight = 1/n_b: the body is split into n_b
  sub-bodies of mass m / n_b, and the merge is the average of the n_b sub-body velocities,
  i.e. every impulse applied with the full mass; with over-relaxation omega
  (``Settings.split_relaxation``; 0 < omega < 2 keeps the convergence proof, method.md 1.7)
  scale = max(1, n_b / omega) and weight = 1 / scale: the Cauchy-Schwarz bound n_b assumes
  all of a body's contacts push it one way; over-relaxation takes back part of that slack,
  but a body with one block has none to take (with scale < 1 its lone block would
  overshoot, measured: a bounce 58 % too high). n_b counts the blocks touching b that can
  act this step: touching or penetrating, carrying a warm-start impulse, or closing their
  gap within the step at the approach speed they start with plus what gravity adds (|g| dt^2;
  without that margin a card landing on the card house was undercounted and the
  over-relaxed split blew it up at step 3, measured). PhysX recounts active
  blocks too). A speculative contact a body's neighbour keeps 2 cm away would otherwise
  split the body as much as one carrying its weight: a 210-box pyramid's boxes counted
  their idle side contacts, and every sweep moved them that much less (the split
  schedules' stiffness limit scales with 1 / sqrt(n_b): solvers/contact_spring.py);
* projected Jacobi with relaxation omega (``MODE_JACOBI``): scale = 1/omega, weight =
  omega, i.e. mass splitting with one global split factor 1/omega instead of each
  body's own count n_b. The step becomes lambda += omega * dlambda (K scaled by
  1/omega), and the impulse written to the body equals the change of the accumulated
  lambda, so warm starting stays consistent. The ``jacobi`` solver without a ``relaxation``
  option (``MODE_JACOBI_BOUNDED``) takes the larger of 1/omega and the split mass splitting
  would give its busiest body, every block counted (n_b / split_relaxation, n_b alone while
  an impact arrives): one global factor still, but one the split's convergence proof covers.
  A fixed 1/omega = 4 overshoots any body with more than ~8 blocks pushing it one way, and
  every sweep then multiplies the error: the card house's planks touch at up to 40 points,
  and projected Jacobi threw it apart at every iteration count, worst at 30 (1580 m/s at
  step 5; docs/method-notes.md). An explicit ``relaxation`` is taken as given (plain Jacobi,
  relaxation 1, is what tests/test_solvers.py shows failing);
* warm start: scale = 1, weight = 1 (the plain sum of last step's impulses with full
  masses; the PGS solvers use this part too). After the first substep the warm start
  rides on the previous substep's last relax sweep (``sweep_blocks``, ``then_warm``):
  the impulses are applied once more to the block's velocity copies with the scaled
  responses, which the weight turns back into full-mass changes (scale x weight = 1 in
  both modes); one pass over the blocks fewer, and no per-point trip through the body's
  inertia. Not in a step with an impact row: its carried impulse is clamped against the
  merged velocities (impact_carry.clamp_impact_carry), so every substep warm starts in its own pass
  (impact_carry.folds_this_step).
* light bodies: a body resting against one ``Settings.ratio_mass`` times heavier has its blocks
  swept ``Settings.ratio_sweeps`` more times per substep (light_bodies.py says why).
"""


import taichi as ti

from ..awake import body_id, body_total
from ..backend import serialize_light_loops
from ..math3d import cross, mat_vec
from ..prefix_sum import Scanner, exclusive_scan, sort_range
from .contact_spring import (BAUMGARTE_RATE, GRAVITY_REACH, IDLE_SHARE, INV_H, LOAD_BLEND, PRELOAD_LAG, RELAX_PUSH,
                             RESTITUTION_THRESHOLD, SPLIT_BOUND, STEP_DT, support_push)
from .impact_carry import clamp_impact_carry
from .light_bodies import list_light_block, list_light_body, mark_light, reset_light_lists
from .rolling import rolling_impulse
from .normal_target import pushes_fast
from .rows import BIASED, ROLLING, point_impulse, solve_point
from .split_scales import block_weights
from .visit_order import gauss_seidel_block

vec3 = ti.math.vec3

PER_POINT = 0
PER_MANIFOLD = 1
MODE_JACOBI = 0
MODE_SPLIT = 1
MODE_JACOBI_BOUNDED = 2


@ti.data_oriented
class BlockScratch:
    def __init__(self, block_capacity: int, body_capacity: int):
        bc = max(16, block_capacity)
        nb = max(1, body_capacity)
        self.block_capacity = bc
        self.block_count = ti.field(ti.i32, ())
        self.adj_count = ti.field(ti.i32, nb + 1)
        self.adj_start = ti.field(ti.i32, nb + 1)
        self.adj_fill = ti.field(ti.i32, nb)
        self.adj_total = ti.field(ti.i32, ())
        self.adj = ti.field(ti.i32, 2 * bc)
        self.slot_dv = ti.Vector.field(3, ti.f32, 2 * bc)
        self.slot_dw = ti.Vector.field(3, ti.f32, 2 * bc)
        self.active_count = ti.field(ti.i32, nb)  # blocks of the body that can act this step (n_b)
        self.fresh_count = ti.field(ti.i32, nb)  # of those, impacts (new and fast)
        self.scale = ti.field(ti.f32, nb)  # of the blocks counted in n_b
        self.weight = ti.field(ti.f32, nb)
        self.scale_idle = ti.field(ti.f32, nb)  # of the body's other blocks (idle_split)
        self.global_scale = ti.field(ti.f32, ())  # MODE_JACOBI_BOUNDED's one factor, this step
        self.body_capacity = nb
        # light bodies and their blocks' extra sweeps (light_bodies.py)
        self.light = ti.field(ti.i32, nb)  # 1: the body rests against one ratio_mass times heavier
        self.block_light = ti.field(ti.i32, bc)  # 1: one of the block's bodies is light
        self.light_blocks = ti.field(ti.i32, bc)  # the blocks of light bodies, in no set order
        self.light_block_count = ti.field(ti.i32, ())
        self.light_bodies = ti.field(ti.i32, nb)  # the bodies those blocks touch, in no set order
        self.light_body_count = ti.field(ti.i32, ())
        self.light_sweeps = ti.field(ti.i32, ())  # this step's extra sweeps of those blocks (0: none)
        self.scanner = Scanner(nb + 1)


@ti.func
def block_range(c: ti.template(), k: ti.i32, kind: ti.template()):
    start, count, a, b = k, 1, 0, 0
    if ti.static(kind == PER_POINT):
        a = c.body_a[k]
        b = c.body_b[k]
    else:
        start = c.m_start[k]
        count = c.m_count[k]
        a = c.m_body_a[k]
        b = c.m_body_b[k]
    return start, count, a, b


@ti.func
def n_blocks(c: ti.template(), kind: ti.template()) -> ti.i32:
    n = 0
    if ti.static(kind == PER_POINT):
        n = c.count[None]
    else:
        n = c.manifold_count[None]
    return n


@ti.func
def _point_can_act(c: ti.template(), rows: ti.template(), q: ti.i32) -> ti.i32:
    """Point q touches or penetrates, carries a warm-start impulse, or closes its gap within
    the step at its approach speed (rows.prepare_row and the warm-start match ran before).
    Under the paper formulation every point counts, as in the paper: its rigid rows have no
    compliance to absorb a sub-body count that a point joining mid-solve makes too small."""
    sep = c.sep[q]
    closing = sep + ti.min(rows.approach[q], 0.0) * rows.params[STEP_DT] - rows.params[GRAVITY_REACH]
    return ti.cast(sep <= 0.0 or rows.lam[q][0] > 0.0 or closing <= 0.0 or rows.params[BAUMGARTE_RATE] > 0.0,
                   ti.i32)


@ti.func
def _block_can_act(c: ti.template(), rows: ti.template(), k: ti.i32, kind: ti.template()):
    """(whether block k can act, whether it is an impact: a new contact, without a warm-start
    impulse, approaching faster than the restitution threshold)."""
    start, count, _, _ = block_range(c, k, kind)
    act = 0
    warm = 0
    fast = 0
    for q in range(start, start + count):
        act |= _point_can_act(c, rows, q)
        warm |= ti.cast(rows.lam[q][0] > 0.0, ti.i32)
        fast |= ti.cast(rows.approach[q] < -rows.params[RESTITUTION_THRESHOLD], ti.i32)
    return act, act * (1 - warm) * fast


@ti.func
def build_adjacency_loops(s: ti.template(), c: ti.template(), bodies: ti.template(), rows: ti.template(),
                          kind: ti.template(), mode: ti.template(), omega: ti.f32):
    """Each dynamic body's sorted block endpoints, its split count and its scale and weight
    (module docstring; under ``MODE_JACOBI_BOUNDED`` every body takes ``global_scale``, the
    busiest body's split), and the light bodies (marked in the blocks that can act; under a fixed
    Jacobi relaxation, MODE_JACOBI, in every block), all of whose blocks take this step's extra
    sweeps (Settings.ratio_sweeps; ``light_sweeps`` is their count, 0 without a light body:
    light_bodies.py). Reads this step's rows and warm-start impulses (the split count)."""
    nb = bodies.count[None]
    nk = n_blocks(c, kind)
    s.block_count[None] = nk
    reset_light_lists(s)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        s.adj_count[i] = 0
        s.adj_fill[i] = 0
        s.active_count[i] = 0
        s.fresh_count[i] = 0
        s.light[i] = 0
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(nk):
        _, _, a, b = block_range(c, k, kind)
        act = 1
        fresh = 0
        if ti.static(mode != MODE_JACOBI):
            act, fresh = _block_can_act(c, rows, k, kind)
        if act:
            mark_light(s, rows, bodies, a, b)
        if ti.static(mode != MODE_SPLIT):
            act = 1  # one global factor: every block counted
        start, count, _, _ = block_range(c, k, kind)
        for q in range(start, start + count):
            rows.counted[q] = act
        if bodies.inv_mass[a] > 0.0:
            ti.atomic_add(s.adj_count[a], 1)
            ti.atomic_add(s.active_count[a], act)
            ti.atomic_add(s.fresh_count[a], fresh)
        if bodies.inv_mass[b] > 0.0:
            ti.atomic_add(s.adj_count[b], 1)
            ti.atomic_add(s.active_count[b], act)
            ti.atomic_add(s.fresh_count[b], fresh)
    exclusive_scan(s.scanner, s.adj_count, s.adj_start, nb, s.adj_total)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(nk):
        _, _, a, b = block_range(c, k, kind)
        list_light_block(s, k, a, b)
        if bodies.inv_mass[a] > 0.0:
            s.adj[s.adj_start[a] + ti.atomic_add(s.adj_fill[a], 1)] = 2 * k
        if bodies.inv_mass[b] > 0.0:
            s.adj[s.adj_start[b] + ti.atomic_add(s.adj_fill[b], 1)] = 2 * k + 1
    if ti.static(mode == MODE_JACOBI_BOUNDED):
        s.global_scale[None] = 1.0 / omega
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        sort_range(s.adj, s.adj_start[i], s.adj_start[i + 1])
        list_light_body(s, rows, i)
        if ti.static(mode == MODE_JACOBI_BOUNDED):  # max is exact in any order: the same bits
            relax = rows.params[SPLIT_BOUND] if s.fresh_count[i] == 0 else 1.0
            ti.atomic_max(s.global_scale[None], ti.cast(s.adj_count[i], ti.f32) / relax)
        if ti.static(mode == MODE_SPLIT):
            # over-relaxation makes up for the split's slack (n_b contacts rarely push one way),
            # so a body's scale never drops below one sub-body: a lone block stays exact
            # ... but not while an impact arrives: over-relaxing it overshoots
            # (a debris box landing at 9.6 m/s left at 20.8 m/s, docs/method-notes.md)
            relax = omega if s.fresh_count[i] == 0 else 1.0
            split = ti.max(ti.cast(ti.max(s.active_count[i], 1), ti.f32) / relax, 1.0)
            idle = s.adj_count[i] - s.active_count[i]
            s.scale_idle[i] = split
            if idle > 0:  # uncounted blocks that still act must not break B >= A (idle_split)
                share = rows.params[IDLE_SHARE]
                split = split / (1.0 - share)
                s.scale_idle[i] = ti.cast(idle, ti.f32) / share
            s.scale[i] = split
            s.weight[i] = 1.0 / split
        if ti.static(mode == MODE_JACOBI):
            s.scale[i] = 1.0 / omega
            s.weight[i] = omega
            s.scale_idle[i] = 1.0 / omega
    if ti.static(mode == MODE_JACOBI_BOUNDED):
        ti.loop_config(serialize=ti.static(serialize_light_loops()))
        for i in range(nb):
            s.scale[i] = s.global_scale[None]
            s.weight[i] = 1.0 / s.global_scale[None]
            s.scale_idle[i] = s.global_scale[None]


@ti.kernel
def build_adjacency(s: ti.template(), c: ti.template(), bodies: ti.template(), rows: ti.template(),
                    kind: ti.template(), mode: ti.template(), omega: ti.f32):
    build_adjacency_loops(s, c, bodies, rows, kind, mode, omega)


@ti.func
def update_support_loops(s: ti.template(), c: ti.template(), rows: ti.template(), bodies: ti.template(),
                         awake: ti.template(), kind: ti.template(), dispatch: ti.template()):
    """After a step: each dynamic body's support force [N] (the upward part of the normal
    impulses of the contacts that hold it up, over the last substep), averaged over
    ``contact_load_time`` and, for the preload, no faster than the body bounces on its support
    springs (``contact_preload_lag``), and its support point count: the load its contacts'
    springs stiffen for, and preload, next step (contact_spring.supported_load). A point
    counts when it touched at the step's start or carried load: one merely near (a 1 mm cube's
    points 0.3 mm above the ground) took half its neighbours' preload (docs/method-notes.md,
    "Limits"). Every schedule builds the adjacency this walks, so the sum runs in a fixed order."""
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for k in range(body_total(bodies, awake)):
        i = body_id(awake, k)
        if bodies.inv_mass[i] > 0.0:
            force = 0.0
            stiffness = 0.0
            points = 0
            for e in range(s.adj_start[i], s.adj_start[i + 1]):
                slot = s.adj[e]
                start, count, _, _ = block_range(c, slot // 2, kind)
                side = 1.0 if slot % 2 == 1 else -1.0  # body b is pushed along +n, body a along -n
                for q in range(start, start + count):
                    lift = support_push(rows.params, side * c.normal[q])
                    if lift > 0.0:
                        force += ti.max(rows.lam[q][0], 0.0) * rows.params[INV_H] * lift
                        if rows.gamma[q] > 0.0:
                            stiffness += rows.rate[q] * rows.params[INV_H] / rows.gamma[q] * lift  # omega^2 / K
                        if c.sep[q] <= 0.0 or rows.lam[q][0] > 0.0:  # touching, or carried the body
                            points += 1
            blend = rows.params[LOAD_BLEND]
            bodies.support[i] += blend * (force - bodies.support[i])
            if force > 0.0:  # no faster than the body bounces on its support springs: sqrt(k |g| / force)
                bounce = ti.sqrt(stiffness * rows.params[GRAVITY_REACH] / (force * rows.params[STEP_DT] ** 2))
                blend = ti.min(blend, bounce * rows.params[STEP_DT] / rows.params[PRELOAD_LAG])
            bodies.support_slow[i] += blend * (force - bodies.support_slow[i])
            bodies.support_points[i] = points


@ti.kernel
def update_support(s: ti.template(), c: ti.template(), rows: ti.template(), bodies: ti.template(),
                   awake: ti.template(), kind: ti.template(), dispatch: ti.template()):
    update_support_loops(s, c, rows, bodies, awake, kind, dispatch)


@ti.func
def gather_body(s: ti.template(), bodies: ti.template(), dv_extra: vec3, i: ti.i32, listed: ti.template() = False):
    """Dynamic body i adds its slots in their fixed order, then ``dv_extra`` (gravity of
    the next substep when a relax sweep carries its warm start, else zero). ``listed``: an
    extra sweep's gather, the slots of light bodies' blocks only (the others hold the biased
    sweep's changes, already added; light_bodies.py), and no ``dv_extra``."""
    if bodies.inv_mass[i] > 0.0:
        dv = vec3(0.0)
        dw = vec3(0.0)
        for e in range(s.adj_start[i], s.adj_start[i + 1]):
            slot = s.adj[e]
            if ti.static(listed):
                if s.block_light[slot // 2]:
                    dv += s.slot_dv[slot]
                    dw += s.slot_dw[slot]
            else:
                dv += s.slot_dv[slot]
                dw += s.slot_dw[slot]
        if ti.static(listed):
            bodies.lin_vel[i] += dv
        else:
            bodies.lin_vel[i] = bodies.lin_vel[i] + dv_extra + dv  # gravity first, as its own pass did
        bodies.ang_vel[i] += dw


@ti.func
def gather_slots(s: ti.template(), bodies: ti.template(), awake: ti.template(), dv_extra: vec3, active: ti.i32):
    """``gather_body`` for every body (``awake``: or the awake ones, awake.py); ``active`` = 0
    runs the loop zero times (it stays a top-level, parallel loop)."""
    for k in range(body_total(bodies, awake) * active):
        gather_body(s, bodies, dv_extra, body_id(awake, k))


@ti.func
def _warm_delta(rows: ti.template(), c: ti.template(), bodies: ti.template(), a: ti.i32, b: ti.i32,
                start: ti.i32, count: ti.i32, friction: ti.template()):
    """Velocity changes of a block's bodies under its accumulated impulses, full masses."""
    dva, dwa, dvb, dwb = vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0)
    for q in range(start, start + count):
        imp = point_impulse(rows, c, q)
        ta = cross(rows.ra[q], imp)
        tb = cross(rows.rb[q], imp)
        if ti.static(friction & ROLLING):
            ta += rolling_impulse(rows, c, q)
            tb += rolling_impulse(rows, c, q)
        dva -= bodies.inv_mass[a] * imp
        dwa -= mat_vec(bodies.inv_inertia_world[a], ta)
        dvb += bodies.inv_mass[b] * imp
        dwb += mat_vec(bodies.inv_inertia_world[b], tb)
    return dva, dwa, dvb, dwb


@ti.func
def _apply_accumulated(rows: ti.template(), c: ti.template(), friction: ti.template(), q: ti.i32, va: vec3, wa: vec3,
                       vb: vec3, wb: vec3):
    """Point q's accumulated impulses applied to velocity copies with the schedule's scaled
    responses (rows.prepare_response)."""
    lam = rows.lam[q]
    imp = point_impulse(rows, c, q)
    ra_ = rows.resp_a[q]
    rb_ = rows.resp_b[q]
    dw_a = vec3(0.0)
    dw_b = vec3(0.0)
    for e in ti.static(range(3)):
        dw_a += vec3(ra_[e, 0], ra_[e, 1], ra_[e, 2]) * lam[e]
        dw_b += vec3(rb_[e, 0], rb_[e, 1], rb_[e, 2]) * lam[e]
    if ti.static(friction & ROLLING):
        roll = rolling_impulse(rows, c, q)
        dw_a += mat_vec(rows.roll_resp_a[q], roll)
        dw_b += mat_vec(rows.roll_resp_b[q], roll)
    return va - rows.lin_a[q] * imp, wa - dw_a, vb + rows.lin_b[q] * imp, wb + dw_b


@ti.func
def warm_block(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), kind: ti.template(),
               friction: ti.template(), k: ti.i32):
    """Block k's share of the warm start, into its two slots (an impact row's carried impulse
    clamped first: impact_carry.clamp_impact_carry)."""
    start, count, a, b = block_range(c, k, kind)
    for q in range(start, start + count):
        clamp_impact_carry(rows, c, bodies, q)
    dva, dwa, dvb, dwb = _warm_delta(rows, c, bodies, a, b, start, count, friction)
    s.slot_dv[2 * k] = dva
    s.slot_dw[2 * k] = dwa
    s.slot_dv[2 * k + 1] = dvb
    s.slot_dw[2 * k + 1] = dwb


@ti.func
def warm_start_blocks(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                      awake: ti.template(), kind: ti.template(), friction: ti.template(), gravity: vec3, h: ti.f32,
                      active: ti.i32):
    """Gravity, then last step's matched impulses with the full masses (method.md 1.10):
    one loop over blocks into the slots, one fixed-order gather per body that adds
    ``gravity * h`` too. Two loops: at a kernel's top level each runs in parallel; inside
    a serialized loop (solvers/substep.py) both run in order. ``active`` = 0 skips it."""
    for k in range(s.block_count[None] * active):
        warm_block(s, rows, c, bodies, kind, friction, k)
    gather_slots(s, bodies, awake, gravity * h, active)


@ti.func
def sweep_block(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), kind: ti.template(),
                mode: ti.template(), friction: ti.template(), then_warm: ti.i32, k: ti.i32, substep: ti.i32) -> ti.i32:
    """Block k solved on its own copies of its bodies' velocities (read from before the
    sweep); the changes, weighted, go to its two slots. Returns 1 when a biased row of it
    pushes fast (normal_target.pushes_fast: its substep gets a second relax sweep), else 0."""
    start, count, a, b = block_range(c, k, kind)
    va0, wa0 = bodies.lin_vel[a], bodies.ang_vel[a]
    vb0, wb0 = bodies.lin_vel[b], bodies.ang_vel[b]
    va, wa, vb, wb = va0, wa0, vb0, wb0
    if ti.static(kind == PER_POINT):
        for i in range(count):  # a per-point block has one point
            va, wa, vb, wb = solve_point(rows, c, bodies, start + i, va, wa, vb, wb, mode, friction)
    else:
        va, wa, vb, wb = gauss_seidel_block(rows, c, bodies, start, count, substep, va, wa, vb, wb, mode, friction)
    fast = 0
    if ti.static(mode == BIASED):
        if rows.params[RELAX_PUSH] > 0.0:  # off: one read per block
            for q in range(start, start + count):
                fast = ti.max(fast, pushes_fast(rows, c, q))
    if then_warm:
        # the next substep's warm start, applied once more to the copies with the scaled
        # responses: scale x weight = 1 for every Jacobi-family body (module docstring),
        # so after the weight this is the full-mass warm start of ``_warm_delta``, read
        # from the precomputed rows instead of rebuilt through each body's inertia
        for q in range(start, start + count):
            va, wa, vb, wb = _apply_accumulated(rows, c, friction, q, va, wa, vb, wb)
    wa_, wb_ = block_weights(s, rows, start, a, b)
    dva = (va - va0) * wa_
    dwa = (wa - wa0) * wa_
    dvb = (vb - vb0) * wb_
    dwb = (wb - wb0) * wb_
    s.slot_dv[2 * k] = dva
    s.slot_dw[2 * k] = dwa
    s.slot_dv[2 * k + 1] = dvb
    s.slot_dw[2 * k + 1] = dwb
    return fast


@ti.func
def sweep_blocks(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                 kind: ti.template(), mode: ti.template(), friction: ti.template(), then_warm: ti.i32, gravity: vec3,
                 h: ti.f32, substep: ti.i32, active: ti.i32 = 1):
    """One Jacobi sweep over all blocks from the same velocities, then the per-body merge.

    ``then_warm`` (the last relax sweep of a substep that has a successor, in a step without an
    impact row: impact_carry.folds_this_step): the block's
    impulses are final for this substep, so its slots also carry the next substep's warm
    start, and the gather adds the next substep's gravity: one block pass and two body
    passes fewer per substep than a separate gravity pass and warm-start pass. A biased
    sweep sets ``rows.fast_push`` when a row pushes fast (normal_target.pushes_fast; every block that
    finds one writes the same 1). ``active`` = 0 runs both loops zero times (they stay
    top-level, parallel loops)."""
    for k in range(s.block_count[None] * active):
        if sweep_block(s, rows, c, bodies, kind, mode, friction, then_warm, k, substep):
            rows.fast_push[None] = 1
    gather_slots(s, bodies, awake, gravity * h * ti.cast(then_warm, ti.f32), active)


@ti.kernel
def warm_start(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
               kind: ti.template(), friction: ti.template(), gravity: vec3, h: ti.f32):
    warm_start_blocks(s, rows, c, bodies, awake, kind, friction, gravity, h, 1)


@ti.kernel
def jacobi_sweep(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                 kind: ti.template(), mode: ti.template(), friction: ti.template(), then_warm: ti.i32, gravity: vec3,
                 h: ti.f32, substep: ti.i32):
    sweep_blocks(s, rows, c, bodies, awake, kind, mode, friction, then_warm, gravity, h, substep)


@ti.func
def sweep_light_blocks(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(),
                       kind: ti.template(), friction: ti.template(), substep: ti.i32):
    """An extra biased sweep (Settings.ratio_sweeps): the blocks of light bodies alone, then their
    bodies add those blocks' slots (light_bodies.py)."""
    for j in range(s.light_block_count[None]):
        if sweep_block(s, rows, c, bodies, kind, BIASED, friction, 0, s.light_blocks[j], substep):
            rows.fast_push[None] = 1
    for j in range(s.light_body_count[None]):
        gather_body(s, bodies, vec3(0.0), s.light_bodies[j], True)


@ti.kernel
def light_sweep(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), kind: ti.template(),
                friction: ti.template(), substep: ti.i32):
    sweep_light_blocks(s, rows, c, bodies, kind, friction, substep)
