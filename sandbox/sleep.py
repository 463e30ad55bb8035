"""Sleeping (the ``sleeping`` effect): resting islands stop being simulated until touched.

After every step of a sleeping world (``after_step``): each awake body's rest timer grows by
the step while its speed stays below ``Settings.sleep_linear_speed`` and its angular speed
below ``sleep_angular_speed``, and restarts otherwise; the awake bodies' islands are
labelled (islands.py); an island whose least rested body has rested ``Settings.sleep_time``
falls asleep. Its bodies' velocities are zeroed (a sleeping body is at rest; Box2D does the
same), their pose becomes their good state, and their shapes' warm-start impulses and
manifolds go to the store (sleep_store.py).

A sleeping body is in none of the step's lists (awake.py): its shapes are not in the grid
the awake shapes search, it is not integrated, it is in no contact, its pairs are not
narrow-phased again. Its shapes sit in a second grid, rebuilt when the sleeping set
changes, that awake shapes also search (pair_search._visit_sleepers): an awake-sleeping pair
is narrow-phased like any other, and if it has points the sleeping island is marked
(awake.note_touch), woken, and the collision of that step done again from the same state
(``wake_touched``), so the woken island's contacts are solved in the very step the touch
began, with the stored manifolds and impulses (Box2D wakes a touched island mid-step too).
Events wake islands from the host (``wake``): a velocity or impulse, a removal or fracture
(the islands of the bodies named), gravity, solver, time-step and effects changes (all of
them), ``World.wake``. Waking restores the records, restarts the timers and puts the bodies
back in the lists. The lists and the grid are rebuilt with prefix sums in body and shape
order, only when something falls asleep or wakes: deterministic, and a settled world's step
visits no sleeping item at all.

The buffers are allocated the first time a world of this capacity class sleeps, so a world
without the effect allocates and compiles none of this (house rule 8).
"""

import numpy as np
import taichi as ti

from .awake import ShapeList, body_id, body_total
from .backend import serialize_light_loops
from .bodies import save_body_state, update_body_inertia
from .broadphase import SPECULATIVE_OFF, Broadphase, build_dynamic_grid_loops
from .dispatch import PARALLEL
from .host_counters import scalar_reader
from .islands import Islands, label_islands, label_rounds, start_labels
from .narrowphase.manifold import MAX_POINTS
from .prefix_sum import Scanner, exclusive_scan
from .sleep_store import FALLING, WAKING, SleepStore, restore_wakers, save_sleepers

vec3 = ti.math.vec3

SPLIT, FALLING_COUNT, AWAKE_ISLANDS, SLEEPING_BODIES, SLEEPING_ISLANDS, GRID_ENTRIES = range(6)
"""The slots of ``SleepBuffers.status``, read by the host once per step and after each event."""
NEVER = 3.0e38


@ti.data_oriented
class SleepBuffers:
    """A sleeping world's state, and the ``awake`` argument of its kernels (awake.py)."""

    compact = True

    def __init__(self, caps, islands: Islands):
        nb, ns = max(1, caps.bodies), max(1, caps.shapes)
        self.islands = islands
        self.body_count = ti.field(ti.i32, ())
        self.body_ids = ti.field(ti.i32, nb)
        self.shape_count = ti.field(ti.i32, ())
        self.shape_ids = ti.field(ti.i32, ns)
        self.sleepers = ShapeList(ns)  # the sleeping shapes: what the grid holds
        self.grid = Broadphase(ns, caps.grid_entries, 16, 16, 1, reuses_pairs=False)  # only its dynamic grid is used
        self.asleep = ti.field(ti.i32, nb)
        self.timer = ti.field(ti.f32, nb)  # [s] how long the body has rested
        self.change = ti.field(ti.i32, nb)  # sleep_store.FALLING / WAKING during an event, else 0
        self.island_rest = ti.field(ti.f32, nb)  # per island label: its least rested body's timer [s]
        self.wake_mark = ti.field(ti.i32, nb)  # per island label: wake it
        self.touched = ti.field(ti.i32, ())  # marks set since the last wake
        self.resting = ti.field(ti.i32, ())  # 1: rest timers and islands run (sleeping on); 0: the lists only
        self.status = ti.field(ti.i32, 8)
        n = max(nb, ns) + 1
        self.flag = ti.field(ti.i32, n)
        self.rank = ti.field(ti.i32, n)
        self.scanner = Scanner(n)
        self.store = SleepStore(max(16, caps.pairs) * MAX_POINTS, caps.pairs, ns)
        self.grid_full = False
        """Set by the host when the sleeping shapes' grid overflowed its entries: the buffers grow
        before the next collision (edits.grow_if_needed), as for the awake grid."""
        self.host_reads = None  # _host_reads: made at the first read, once the fields are placed
        self.idle = False
        """The last step ran with no awake body and nothing has woken since: the next step
        would change no bit (no awake shape to collide, no row, no body to move), so the
        stepper skips it. Every change of the awake set clears it (``note_grid``)."""


class _HostReads:
    """A sleeping world's per-step reads (host_counters.scalar_reader): its touched mark and
    each slot of its status."""

    def __init__(self, sl: SleepBuffers):
        self.touched = scalar_reader(sl.touched)
        self.status = tuple(scalar_reader(sl.status, k) for k in range(sl.status.shape[0]))


def _host_reads(sl: SleepBuffers) -> _HostReads:
    """``sl``'s readers, made at its first read (its fields are placed by then)."""
    if sl.host_reads is None:
        sl.host_reads = _HostReads(sl)
    return sl.host_reads


def note_grid(sl: SleepBuffers) -> None:
    """After an event changed the awake set and rebuilt the sleeping grid: did it fit? The
    next step is not idle."""
    sl.grid_full = int(sl.status[GRID_ENTRIES]) > sl.grid.entry_capacity
    sl.idle = False


def islands_of(buf) -> Islands:
    """The island labels of a buffer set, allocated on first use."""
    if buf.islands is None:
        buf.islands = Islands(buf.caps.bodies)
    return buf.islands


def buffers_of(buf) -> SleepBuffers:
    if buf.sleep is None:
        buf.sleep = SleepBuffers(buf.caps, islands_of(buf))
    return buf.sleep


# ---------------------------------------------------------------------------- kernels
@ti.func
def _refresh(sl: ti.template(), shapes: ti.template(), bodies: ti.template(), bp: ti.template(), err: ti.template(),
             margin: ti.f32):
    """The awake lists, the sleeping shapes' list and grid, and the sleeping counts, from ``asleep``."""
    nb = bodies.count[None]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        sl.flag[i] = 1 if bodies.inv_mass[i] > 0.0 and sl.asleep[i] == 0 else 0
    exclusive_scan(sl.scanner, sl.flag, sl.rank, nb, sl.body_count)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        if sl.flag[i]:
            sl.body_ids[sl.rank[i]] = i
    ns = shapes.dynamic_count[None]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(ns):
        sl.flag[k] = 1 - sl.asleep[shapes.body[shapes.dynamic_ids[k]]]
    exclusive_scan(sl.scanner, sl.flag, sl.rank, ns, sl.shape_count)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(ns):
        if sl.flag[k]:
            sl.shape_ids[sl.rank[k]] = shapes.dynamic_ids[k]
        sl.flag[k] = 1 - sl.flag[k]
    exclusive_scan(sl.scanner, sl.flag, sl.rank, ns, sl.sleepers.shape_count)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(ns):
        if sl.flag[k]:
            sl.sleepers.shape_ids[sl.rank[k]] = shapes.dynamic_ids[k]
            bp.refitted[shapes.dynamic_ids[k]] = 0  # a sleeper's partners need not search for it
    sl.grid.cell_size[None] = bp.cell_size[None]
    build_dynamic_grid_loops(sl.grid, shapes, bodies, margin, 0.0, 0.0, SPECULATIVE_OFF, err, sl.sleepers, PARALLEL)
    bp.listed[None] = 0  # the awake shapes, their slots and their sleeping partners changed
    sl.status[GRID_ENTRIES] = sl.grid.entry_total[None]
    sl.status[SLEEPING_BODIES] = 0
    sl.status[SLEEPING_ISLANDS] = 0
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        if sl.asleep[i]:
            ti.atomic_add(sl.status[SLEEPING_BODIES], 1)
            if sl.islands.label[i] == i:
                ti.atomic_add(sl.status[SLEEPING_ISLANDS], 1)


@ti.kernel
def _start(sl: ti.template(), shapes: ti.template(), bodies: ti.template(), bp: ti.template(), err: ti.template(),
           margin: ti.f32):
    """Everything awake, nothing stored, no marks."""
    for i in range(bodies.count[None]):
        sl.asleep[i] = 0
        sl.timer[i] = 0.0
        sl.change[i] = 0
        sl.wake_mark[i] = 0
    for h, i in sl.store.point_first:
        sl.store.point_first[h, i] = 0
        sl.store.point_last[h, i] = 0
        sl.store.pair_first[h, i] = 0
        sl.store.pair_last[h, i] = 0
    sl.store.parity[None] = 0
    sl.touched[None] = 0
    _refresh(sl, shapes, bodies, bp, err, margin)


@ti.kernel
def restart_after_rebuild(sl: ti.template(), shapes: ti.template(), bodies: ti.template(), bp: ti.template(),
                          err: ti.template(), margin: ti.f32):
    """After ``asleep``, ``timer``, labels and store were written from the host (a rebuild)."""
    for i in range(bodies.count[None]):
        sl.change[i] = 0
        sl.wake_mark[i] = 0
    sl.touched[None] = 0
    _refresh(sl, shapes, bodies, bp, err, margin)


@ti.func
def rest_and_label_loops(sl: ti.template(), c: ti.template(), bodies: ti.template(), h: ti.f32, lin: ti.f32,
                         ang: ti.f32, rest_time: ti.f32, first: ti.template()):
    """Rest timers (``first``: once per step), island labels, and which islands fall asleep
    (``status``; applied by ``after_step``). At a kernel's top level: the fused step runs it
    inside ``step_kernels.finish_step``."""
    active = sl.resting[None]  # 0: sleeping is off in a world that keeps its awake lists (stop)
    if ti.static(first):
        n_rest = body_total(bodies, sl) * active
        ti.loop_config(serialize=ti.static(serialize_light_loops()))
        for k in range(n_rest):
            i = body_id(sl, k)
            if bodies.lin_vel[i].norm_sqr() <= lin * lin and bodies.ang_vel[i].norm_sqr() <= ang * ang:
                sl.timer[i] += h
            else:
                sl.timer[i] = 0.0
        start_labels(sl.islands, bodies, sl, active)
    label_rounds(sl.islands, c, bodies, sl, active)
    n = body_total(bodies, sl) * active
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        sl.island_rest[body_id(sl, k)] = NEVER
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(sl, k)
        ti.atomic_min(sl.island_rest[sl.islands.label[i]], sl.timer[i])  # a min: the same whatever the order
    sl.status[FALLING_COUNT] = 0
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(sl, k)
        sl.change[i] = 0
        if sl.island_rest[sl.islands.label[i]] >= rest_time:
            sl.change[i] = FALLING
            ti.atomic_add(sl.status[FALLING_COUNT], 1)
    sl.status[SPLIT] = sl.islands.split[None]
    sl.status[AWAKE_ISLANDS] = sl.islands.count[None]


@ti.kernel
def _rest_and_label(sl: ti.template(), c: ti.template(), bodies: ti.template(), h: ti.f32, lin: ti.f32, ang: ti.f32,
                    rest_time: ti.f32, first: ti.template()):
    rest_and_label_loops(sl, c, bodies, h, lin, ang, rest_time, first)


def rest_arguments(h: float, settings) -> tuple:
    """The scalars of ``rest_and_label_loops`` after ``c`` and ``bodies``: step [s], speeds, time."""
    return h, settings.sleep_linear_speed, settings.sleep_angular_speed, settings.sleep_time


@ti.kernel
def _fall_asleep(sl: ti.template(), hist: ti.template(), cache: ti.template(), shapes: ti.template(),
                 bodies: ti.template(), bp: ti.template(), err: ti.template(), margin: ti.f32):
    save_sleepers(sl.store, hist, cache, shapes, sl.asleep, sl.change)
    n = body_total(bodies, sl)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n):
        i = body_id(sl, k)
        if sl.change[i] == FALLING:
            sl.asleep[i] = 1
            bodies.lin_vel[i] = vec3(0.0)
            bodies.ang_vel[i] = vec3(0.0)
            update_body_inertia(bodies, i)  # the inertia and good state of the pose it sleeps in
            save_body_state(bodies, i)
            sl.change[i] = 0
            if sl.islands.label[i] == i:
                ti.atomic_sub(sl.status[AWAKE_ISLANDS], 1)
    _refresh(sl, shapes, bodies, bp, err, margin)


@ti.kernel
def _wake(sl: ti.template(), hist: ti.template(), cache: ti.template(), shapes: ti.template(), bodies: ti.template(),
          bp: ti.template(), err: ti.template(), margin: ti.f32, everyone: ti.i32):
    """Wake the marked islands (``everyone``: all of them)."""
    nb = bodies.count[None]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        sl.change[i] = 0
        if sl.asleep[i]:
            if everyone or sl.wake_mark[sl.islands.label[i]]:
                sl.change[i] = WAKING
    restore_wakers(sl.store, hist, cache, shapes, sl, sl.change)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        if sl.change[i] == WAKING:
            sl.asleep[i] = 0
            sl.timer[i] = 0.0
            if sl.islands.label[i] == i:
                ti.atomic_add(sl.status[AWAKE_ISLANDS], 1)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(nb):
        sl.change[i] = 0
        sl.wake_mark[i] = 0
    sl.touched[None] = 0
    _refresh(sl, shapes, bodies, bp, err, margin)


@ti.kernel
def _mark(sl: ti.template(), ids: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    for t in range(ids.shape[0]):
        i = ids[t]
        if sl.asleep[i]:
            sl.wake_mark[sl.islands.label[i]] = 1
            ti.atomic_add(sl.touched[None], 1)


# ---------------------------------------------------------------------------- host side
def start(buf, margin: float, resting: bool = True) -> None:
    """Every body awake and listed. ``resting``: turn sleeping on (rest timers run, the islands
    labelled from the last contacts); False: the lists only, for a world that keeps them with
    sleeping off (``stop``), after a rebuild."""
    sl = buffers_of(buf)
    _start(sl, buf.shapes, buf.bodies, buf.bp, buf.errors, margin)
    sl.resting[None] = int(resting)
    if resting:
        sl.status[AWAKE_ISLANDS] = label_islands(sl.islands, buf.contacts, buf.bodies, sl)
    note_grid(sl)


def stop(buf, margin: float) -> None:
    """Turn sleeping off but keep the buffers as the world's ``awake`` set (edits.Edits.awake_set):
    every island wakes, and the rest timers and island labels stop (``resting`` 0: their loops
    run zero times). The step's kernels stay the instances they are; going back to awake.EVERY
    instantiated every one of them again, a pause of the running world (the playground: 3.3 s
    with a warm kernel cache, 10.5 s with a cold one)."""
    wake(buf, margin)
    buf.sleep.resting[None] = 0


def after_step(buf, h: float, settings, labelled: bool = False) -> None:
    """Rest timers, islands, and the islands that fall asleep (module docstring). ``labelled``:
    the step's last kernel has run ``rest_and_label_loops`` already (the fused step)."""
    sl = buf.sleep
    args = (sl, buf.contacts, buf.bodies, *rest_arguments(h, settings))
    if not labelled:
        _rest_and_label(*args, True)
    read = _host_reads(sl)
    while read.status[SPLIT]() > 0:  # labels not converged in ROUNDS rounds: more rounds, then decide again
        _rest_and_label(*args, False)
    sl.idle = read.status[AWAKE_ISLANDS]() == 0  # every dynamic body slept through this step
    if read.status[FALLING_COUNT]() > 0:
        _fall_asleep(sl, buf.history, buf.manifold_cache, buf.shapes, buf.bodies, buf.bp, buf.errors,
                     settings.contact_margin)
        note_grid(sl)


def precompile(buf, margin: float) -> None:
    """Between steps, before anything sleeps: compile what an island falling asleep and a wake
    launch (a web world stalled ~1 s at each, the playground's steps 37 and 144). No change: no
    body falling, the store's other half is built empty, twice (parity back); no mark, no wake."""
    sl = buf.sleep
    if int(sl.status[SLEEPING_BODIES]) > 0:
        return
    for _ in range(2):
        _fall_asleep(sl, buf.history, buf.manifold_cache, buf.shapes, buf.bodies, buf.bp, buf.errors, margin)
    _wake(sl, buf.history, buf.manifold_cache, buf.shapes, buf.bodies, buf.bp, buf.errors, margin, 0)
    note_grid(sl)


def wake_touched(buf, margin: float) -> bool:
    """After a narrowphase: wake the sleeping islands it found touched, handing the manifold
    cache's halves back so the collision can be redone (True: redo it)."""
    sl = buf.sleep
    if _host_reads(sl).touched() == 0:
        return False
    cache = buf.manifold_cache
    cache.parity[None] = 1 - int(cache.parity[None])
    _wake(sl, buf.history, cache, buf.shapes, buf.bodies, buf.bp, buf.errors, margin, 0)
    note_grid(sl)
    return True


def wake(buf, margin: float, bodies=None) -> None:
    """Between steps: wake the islands of ``bodies`` (indices), or every island (None)."""
    sl = buf.sleep
    if bodies is None:
        if int(sl.status[SLEEPING_BODIES]) > 0:
            _wake(sl, buf.history, buf.manifold_cache, buf.shapes, buf.bodies, buf.bp, buf.errors, margin, 1)
            note_grid(sl)
        return
    ids = np.asarray(list(bodies), dtype=np.int32)
    if len(ids) == 0:
        return
    _mark(sl, ids)
    if int(sl.touched[None]) > 0:
        _wake(sl, buf.history, buf.manifold_cache, buf.shapes, buf.bodies, buf.bp, buf.errors, margin, 0)
        note_grid(sl)


def counts(buf) -> dict[str, int]:
    """Sleeping bodies, and islands awake and asleep (the awake ones as of the last step)."""
    s = buf.sleep.status.to_numpy()
    return {"sleeping_bodies": int(s[SLEEPING_BODIES]), "islands": int(s[AWAKE_ISLANDS] + s[SLEEPING_ISLANDS])}


def asleep_mask(buf, n: int) -> np.ndarray:
    return buf.sleep.asleep.to_numpy()[:n].astype(bool)
