"""Mass splitting (Tonge et al. 2012, method.md 1.6 and 1.11): every contact block solved at
once on its own copies of its bodies, each body's impulses merged by a deterministic
scatter/gather. Projected Jacobi is the same schedule with one global split factor.

A *block* is either one contact point (``mass-splitting``, ``jacobi``) or one manifold,
i.e. all points of one shape pair (``block-mass-splitting``; also the unit the PGS
solvers visit). Each block has two endpoints (its bodies a and b). For every dynamic
body we build, per step, the sorted list of endpoints touching it (counting sort by
body, then a per-body sort, so thread timing never changes the order: block_adjacency.py). A sweep writes
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
  inertia. In a step with an impact row, what an impact carried beyond its stop is then taken
  back after the merge (``clamp_folded_carries``, impact_carry.py).
* light bodies: a body resting against one ``Settings.ratio_mass`` times heavier has its blocks
  swept ``Settings.ratio_sweeps`` more times per substep (light_bodies.py says why).
"""


import taichi as ti

from ..awake import body_id, body_total
from ..math3d import cross, mat_vec
from .block_adjacency import PER_POINT, block_range, slot_change, store_slots
from .contact_spring import GRAVITY_REACH, INV_H, LOAD_BLEND, PRELOAD_LAG, RELAX_PUSH, STEP_DT, support_push
from .impact_carry import clamp_impact_carry, scale_carry, stopping_impulse
from .rolling import rolling_impulse
from .normal_target import pushes_fast
from .rows import BIASED, ROLLING, point_impulse, solve_point
from .split_scales import block_weights
from .visit_order import gauss_seidel_block

vec3 = ti.math.vec3

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
                    slot_dv, slot_dw = slot_change(s, slot)
                    dv += slot_dv
                    dw += slot_dw
            else:
                slot_dv, slot_dw = slot_change(s, slot)
                dv += slot_dv
                dw += slot_dw
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
    store_slots(s, k, dva, dwa, dvb, dwb)


@ti.func
def clamp_folded_carry(rows: ti.template(), c: ti.template(), bodies: ti.template(), friction: ti.template(),
                       q: ti.i32):
    """Listed point q (impact_carry.list_carry_rows), after a relax sweep carried the next
    substep's warm start whole: what it carried beyond the impulse that stops its approach, at
    the merged velocities without its own carry (gravity and the other rows' carries in them),
    taken back with full masses. The fold's carry is the full-mass one (scale x weight = 1),
    so this is ``clamp_impact_carry`` moved after the merge, where a Gauss-Seidel pass can see
    the velocities: the listed rows one after another, each seeing the ones before it."""
    lam = rows.lam[q]
    if lam[0] > 0.0:
        a = c.body_a[q]
        b = c.body_b[q]
        dva, dwa, dvb, dwb = _warm_delta(rows, c, bodies, a, b, q, 1, friction)
        va = bodies.lin_vel[a] - dva + cross(bodies.ang_vel[a] - dwa, rows.ra[q])
        vb = bodies.lin_vel[b] - dvb + cross(bodies.ang_vel[b] - dwb, rows.rb[q])
        stop = stopping_impulse(rows, c, q, va, vb)
        if stop < lam[0]:
            ratio = stop / lam[0]
            scale_carry(rows, q, ratio)
            back = ratio - 1.0
            if bodies.inv_mass[a] > 0.0:
                bodies.lin_vel[a] += back * dva
                bodies.ang_vel[a] += back * dwa
            if bodies.inv_mass[b] > 0.0:
                bodies.lin_vel[b] += back * dvb
                bodies.ang_vel[b] += back * dwb


@ti.func
def clamp_folded_carries(rows: ti.template(), c: ti.template(), bodies: ti.template(), friction: ti.template()):
    """``clamp_folded_carry`` for every listed point in order, on the calling thread (none in a
    step without an impact row)."""
    for i in range(rows.carry_count[None]):
        clamp_folded_carry(rows, c, bodies, friction, rows.carry_rows[i])


@ti.kernel
def clamp_folded_carries_kernel(rows: ti.template(), c: ti.template(), bodies: ti.template(),
                                friction: ti.template()):
    """``clamp_folded_carries`` as a launch of its own (the per-phase loop, step.py)."""
    ti.loop_config(serialize=True)
    for _ in range(1):
        clamp_folded_carries(rows, c, bodies, friction)


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
    store_slots(s, k, (va - va0) * wa_, (wa - wa0) * wa_, (vb - vb0) * wb_, (wb - wb0) * wb_)
    return fast


@ti.func
def sweep_blocks(s: ti.template(), rows: ti.template(), c: ti.template(), bodies: ti.template(), awake: ti.template(),
                 kind: ti.template(), mode: ti.template(), friction: ti.template(), then_warm: ti.i32, gravity: vec3,
                 h: ti.f32, substep: ti.i32, active: ti.i32 = 1):
    """One Jacobi sweep over all blocks from the same velocities, then the per-body merge.

    ``then_warm`` (the last relax sweep of a substep that has a successor; in a step with an
    impact row ``clamp_folded_carries`` follows the merge): the block's
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
