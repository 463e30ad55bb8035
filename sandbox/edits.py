"""A world's contents and every edit of them: the live body list (``BodySpec``s), the host
arrays built from it (build.py) and the device buffers they are uploaded into (buffers.py).

Edits (add, remove, fracture, set a velocity, apply an impulse) run between steps. Those that
change the body list rebuild the host arrays and upload them: every other body keeps its
state (read back from the device first), its contacts' warm-start impulses and its support
loads (renumbered with the shapes and bodies; so does a move to larger buffers), and the
buffers move to a larger capacity class only when the new list needs it (a class once
compiled stays, so removing or fracturing never recompiles for a smaller one).

Fracture (``fracture.py``) replaces a body by its pieces through the same rebuild: piece 0
takes the broken body's index, so the indices of the other bodies never change. The other
pieces of a scripted or API fracture are appended (before any impact pieces); those of an
impact fracture go at the very end, so the indices a scene's timeline was resolved to at
load time stay valid however bodies break on impact. Breakable bodies (``strength``) are
watched by ``impact.py`` only when the scene has some; one that broke in a step is
fractured at the start of the next step, before that step's scripted events, as a logged
event (``take_breaks``: the world applies and logs it), so a replay applies it from the log.

With the ``sleeping`` effect (sleep.py) every edit wakes what it touches: a velocity, an
impulse, a removal or a fracture wakes the islands of the bodies named, and a rebuild carries
the sleeping islands over (their state and their stored impulses and manifolds follow the
bodies' new indices), so dropping bodies beside a sleeping pile leaves it asleep.

Nothing here knows the World or the solvers: the facade (world.py) calls these methods.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import buffers, sleep, sleep_rebuild
from .awake import EVERY
from .backend import loop_arch
from .dispatch import dispatch_for
from .build import host_world, mass_spread, upload
from .errors import CapacityError, SandboxError
from .fracture import FractureError, check_arguments, fracture_body, piece_count
from .host_counters import StepCounters
from .persistence import read_history, write_history
from .scene import quat_to_matrix
from .scene.spec import EventSpec, Scene
from .settings import Settings
from .shapes import HULL, KIND_NAMES


class Edits:
    """The body list, host arrays and device buffers of one world, and their edits."""

    def __init__(self, scene: Scene, settings: Settings, reserve_pieces: int = 0, reserve_kinds: tuple = ()):
        if isinstance(reserve_pieces, bool) or not isinstance(reserve_pieces, (int, np.integer)) or reserve_pieces < 0:
            raise SandboxError(f"reserve_pieces must be an integer >= 0, got {reserve_pieces!r}")
        names = {name: kind for kind, name in KIND_NAMES.items()}
        unknown = [k for k in reserve_kinds if k not in names]
        if unknown:
            raise SandboxError(f"reserve_kinds: unknown shape kind(s) {unknown}; known: {', '.join(names)}")
        self.scene = scene
        self.settings = settings
        self.bodies = list(scene.bodies)  # the live body list (events add and remove)
        self.tail = 0  # pieces of impact fractures at the end of the body list
        self.last_fracture: list = []
        """``fracture.FractureResult`` of each body of the last fracture (how exact its pieces were)."""
        self._breaking: list[int] = []  # bodies that broke in the last step, fractured before the next
        self.sleeping = False  # the sleeping effect is on (set_sleeping)
        self.keeps_awake_lists = False  # once sleeping was on, its buffers stay the awake set (sleep.stop)
        dropped = [b for e in scene.events if e.kind == "drop" for b in e.new_bodies]
        drop_kinds = tuple(sorted({s.kind for b in dropped for s in b.shapes if s.kind in names}))
        reserve = _fracture_reserve(scene) + len(dropped) + int(reserve_pieces)
        self.host = host_world(scene, settings)
        self.kinds = _union_kinds(self.host.kinds, ((HULL,) if reserve - len(dropped) else ())
                                  + tuple(names[k] for k in reserve_kinds + drop_kinds))
        self.reserve_kinds = tuple(sorted(reserve_kinds))
        # a box, capsule or hull may be added (by the caller or the scene's own drops):
        self.anisotropic_reserved = any(k != "sphere" for k in reserve_kinds + drop_kinds)
        # and a body far lighter or heavier than the others (effects.py, light_bodies): a piece, a
        # reserved body or one of a reserved kind may have any mass, a scene's drops have theirs
        any_mass = reserve > len(dropped) or bool(reserve_kinds)
        self.spread_reserved = math.inf if any_mass else dropped_spread(scene.bodies, dropped)
        self._finalizer = None
        self.placed = np.arange(len(self.host.body_arrays["inv_mass"]))  # bodies no narrowphase has seen
        self._acquire(self.host.capacities(reserve_pieces=reserve))
        self._update_breakable()

    # ------------------------------------------------------------------ buffers
    def _acquire(self, caps) -> None:
        self.buf = buffers.acquire(caps)
        self._finalizer = buffers.release_on_collect(self, self.buf)
        self._upload()
        self.counters = StepCounters(self.buf)

    def _upload(self) -> None:
        upload(self.host, self.buf, self.settings.contact_margin, self.placed)

    def placed_seen(self) -> None:
        """A step has passed since the last edit (its narrowphase will not be redone): the bodies
        it placed are no longer new (Bodies.mark_placed)."""
        if len(self.placed):
            self.placed = self.placed[:0]
            self.buf.bodies.placed.fill(0)

    def keep_overlaps(self) -> None:
        """Before the manifold cache is forgotten (an edit, grown buffers, a restored good state):
        count the dynamic bodies of the pairs still marked overlapping as placed again, so that
        the next narrowphase marks those pairs again (and only pairs that deep). Reads the
        contacts only when a pair is marked."""
        c = self.buf.contacts
        n = int(c.count[None])
        if n == 0:
            return
        marked = c.overlap.to_numpy()[:n].astype(bool)
        if not marked.any():
            return
        bodies = np.concatenate([c.body_a.to_numpy()[:n][marked], c.body_b.to_numpy()[:n][marked]])
        bodies = bodies[self.host.body_arrays["inv_mass"][bodies] > 0.0]
        self.placed = np.union1d(self.placed, bodies)
        self.buf.bodies.mark_placed(self.placed)

    def close(self) -> None:
        """Give the device buffers back to the process pool (also done when collected)."""
        if self._finalizer is not None:
            self._finalizer()
            self._finalizer = None

    def grow_if_needed(self) -> bool:
        """After a broadphase overflow (or of a sleeping world's grid of sleeping shapes): move to
        a bigger buffer class, keeping the body state and the sleeping islands."""
        b = self.buf
        counters = self.counters
        entries, pairs = counters.entry_total(), counters.pair_total()
        sleepers_full = self.sleeping and b.sleep.grid_full
        if entries <= counters.entry_capacity and pairs <= counters.pair_capacity and not sleepers_full:
            return False
        if sleepers_full:
            entries = max(entries, 2 * b.caps.grid_entries)
        from .bodies import restore_good_state

        restore_good_state(b.bodies)
        n = len(self.host.body_arrays["inv_mass"])
        for k, v in b.bodies.host_state().items():
            self.host.body_arrays[k] = v[:n]
        caps = b.caps.grown(grid_entries=max(b.caps.grid_entries, 2 * entries), pairs=max(b.caps.pairs, 2 * pairs))
        self.keep_overlaps()
        snap = self._sleep_snapshot()
        carried = self._carried_contacts(n)
        self.close()
        self._acquire(caps)
        same = np.arange(len(self.host.shape_arrays["body"]))
        self._restore_contacts(carried, np.arange(n), same)
        self._sleep_restore(snap, np.arange(n), same)
        return True

    def _rebuild(self, bodies: list, body_map: np.ndarray) -> None:
        """``body_map``: old body index -> new one (-1: gone), the static carrier included."""
        self.keep_overlaps()
        snap = self._sleep_snapshot()
        carried = self._carried_contacts(len(body_map))
        old_shape_body = self.host.shape_arrays["body"]
        self.bodies = bodies
        self.host = host_world(dataclasses.replace(self.scene, bodies=bodies), self.settings)
        body_map = np.asarray(body_map)
        still_new = body_map[self.placed]  # placed by an earlier edit, not yet seen
        self.placed = np.union1d(np.setdiff1d(np.arange(len(self.host.body_arrays["inv_mass"])), body_map),
                                 still_new[still_new >= 0])
        self.kinds = _union_kinds(self.kinds, self.host.kinds)  # a kind once compiled stays: no recompile back
        old = self.buf.caps
        caps = self.host.capacities(pairs=old.pairs, grid_entries=old.grid_entries).covering(old)
        if caps == old:
            self._upload()
        else:
            self.close()
            self._acquire(caps)
        new_count = len(self.host.body_arrays["inv_mass"])
        shape_map = sleep_rebuild.shape_map_for(old_shape_body, self.host.shape_arrays["body"], body_map, new_count)
        self._restore_contacts(carried, body_map, shape_map)
        self._sleep_restore(snap, body_map, shape_map)
        self._update_breakable()

    def _carried_contacts(self, n_bodies: int) -> tuple[dict, dict]:
        """What a rebuild carries for the bodies that stay: the stored impulses of their awake
        contacts (the next step's warm start; the sleeping ones' wait in the sleep store) and
        their support loads (their springs' stiffness and preload, contact_spring.py). Without
        them a resting pile starts the step after an edit cold and soft, and falls for a substep
        before its sweeps catch up (docs/method-notes.md, "Edits: what a rebuild carries")."""
        return read_history(self.buf.history), self.buf.bodies.read_loads(n_bodies)

    def _restore_contacts(self, carried: tuple[dict, dict], body_map: np.ndarray, shape_map: np.ndarray) -> None:
        history, loads = carried
        write_history(self.buf.history, sleep_rebuild.remap_owned(history, "point", shape_map))
        self.buf.bodies.write_loads(loads, np.asarray(body_map, np.int64))

    # ------------------------------------------------------------------ sleeping
    def awake_set(self, sleeping: bool):
        """The ``awake`` argument of the step's kernels (awake.py): a world that has slept keeps
        its sleep buffers with sleeping off (sleep.stop), so that the toggle recompiles nothing."""
        return self.buf.sleep if sleeping or self.keeps_awake_lists else EVERY

    @property
    def dispatch(self):
        """The ``dispatch`` argument of the step's kernels (dispatch.py): from the arch and the
        buffers' body capacity, so it changes only when the buffers grow (a recompile anyway)."""
        return dispatch_for(loop_arch(), self.buf.caps.bodies)

    def set_sleeping(self, on: bool) -> None:
        """Turn the sleeping effect on (everything starts awake) or off (every island wakes, with
        its stored impulses and manifolds)."""
        if on and not self.sleeping:
            sleep.start(self.buf, self.settings.contact_margin)
            self.keeps_awake_lists = True
        elif self.sleeping and not on:
            sleep.stop(self.buf, self.settings.contact_margin)
        self.sleeping = bool(on)

    def precompile_sleeping(self) -> None:
        """With the sleeping effect on, compile its fall-asleep and wake kernels now (sleep.precompile)."""
        if self.sleeping:
            sleep.precompile(self.buf, self.settings.contact_margin)

    def wake(self, indices=None) -> None:
        """Wake the islands of the bodies ``indices`` (checked), or every island (None)."""
        if self.sleeping:
            sleep.wake(self.buf, self.settings.contact_margin, indices)

    def _sleep_snapshot(self):
        if not self.sleeping:
            return None
        return sleep_rebuild.snapshot(self.buf, len(self.host.body_arrays["inv_mass"]), self.host.shape_arrays["body"])

    def _sleep_restore(self, snap, body_map: np.ndarray, shape_map: np.ndarray) -> None:
        if snap is None:
            if self.keeps_awake_lists:  # sleeping off: the lists again, of every body
                sleep.start(self.buf, self.settings.contact_margin, resting=False)
            return
        sleep_rebuild.restore(self.buf, snap, np.asarray(body_map, np.int64), shape_map, self.settings.contact_margin)

    # ------------------------------------------------------------------ queries
    @property
    def body_count(self) -> int:
        return len(self.bodies)

    @property
    def dynamic_count(self) -> int:
        return sum(1 for b in self.bodies if not b.static)

    def body_name(self, i: int) -> str:
        if 0 <= i < len(self.bodies) and self.bodies[i].name:
            return f" ({self.bodies[i].name!r})"
        return ""

    def check_indices(self, indices, what: str, dynamic: bool = False) -> list[int]:
        idx = [indices] if isinstance(indices, (int, np.integer)) else list(indices)
        n = len(self.bodies)
        for i in idx:
            if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < n:
                raise SandboxError(f"{what}: no body {i!r} (the world has bodies 0..{n - 1})")
            if dynamic and self.bodies[i].static:
                raise SandboxError(f"{what}: body {i}{self.body_name(i)} is static and cannot be moved")
        return [int(i) for i in idx]

    def live_specs(self) -> list:
        """The current body list with positions and velocities read back from the device."""
        st = self.buf.bodies.host_state()
        return [dataclasses.replace(b, position=st["pos"][i], orientation=st["rot"][i],
                                    linear_velocity=st["lin_vel"][i], angular_velocity=st["ang_vel"][i])
                for i, b in enumerate(self.bodies)]

    def _check_body_budget(self, count: int, what: str) -> None:
        if count > self.settings.max_bodies:
            raise CapacityError(f"{what} would make {count} bodies; this world holds at most "
                                f"{self.settings.max_bodies} (Settings.max_bodies: raise it with "
                                "World(..., settings=Settings().replace(max_bodies=...)))")

    # ------------------------------------------------------------------ edits of the body list
    def add(self, bodies: list) -> list[int]:
        """Append bodies before the pieces of impact fractures; returns their indices."""
        live = self.live_specs()
        self._check_body_budget(len(live) + len(bodies), "adding bodies")
        at = len(live) - self.tail
        self._rebuild(live[:at] + list(bodies) + live[at:], _shifted(len(live), at, len(bodies)))
        return list(range(at, at + len(bodies)))

    def remove(self, indices: list[int]) -> None:
        """Remove bodies (indices checked by ``check_indices``); later bodies move down."""
        drop = set(indices)
        self.wake(sorted(drop))  # what rested on them falls
        self.tail -= sum(1 for i in drop if i >= len(self.bodies) - self.tail)
        kept = np.array([i not in drop for i in range(len(self.bodies) + 1)])  # + the static carrier
        body_map = np.where(kept, np.cumsum(kept) - 1, -1)
        self._rebuild([b for i, b in enumerate(self.live_specs()) if i not in drop], body_map)

    def check_fracture(self, bodies, pieces: int, seed: int, impulse: float) -> list[int]:
        """The indices to fracture, or SandboxError / FractureError naming what is wrong."""
        try:
            check_arguments(pieces, seed, impulse)
        except FractureError as exc:
            raise FractureError(f"fracture: {exc}") from None
        idx = self.check_indices(bodies, "fracture")
        if not idx:
            raise SandboxError("fracture: no body given")
        if len(set(idx)) != len(idx):
            raise SandboxError(f"fracture: a body is listed twice in {idx}")
        for i in idx:
            if self.bodies[i].static:
                raise SandboxError(f"fracture: body {i}{self.body_name(i)} is static and cannot be fractured")
        return idx

    def fracture(self, idx: list[int], pieces: int, seed: int, impulse: float, impact: bool) -> list[int]:
        """Replace each body of ``idx`` (checked) by its pieces (module docstring); returns the
        pieces' indices. A body that cannot be split raises FractureError, the list unchanged."""
        self.wake(idx)
        live = self.live_specs()
        results = []
        for k, i in enumerate(idx):
            try:
                results.append(fracture_body(live[i], pieces=pieces, seed=int(seed) + k,
                                             impulse=impulse, min_piece_size=self.settings.fracture_min_piece_size))
            except FractureError as exc:
                raise FractureError(f"fracture: body {i}{self.body_name(i)} stays whole: {exc}") from None
        extras = [piece for r in results for piece in r.bodies[1:]]
        self._check_body_budget(len(live) + len(extras),
                                f"fracturing {len(idx)} body(ies) into {len(extras) + len(idx)} pieces")
        for i, r in zip(idx, results):
            live[i] = r.bodies[0]
        at = len(live) if impact else len(live) - self.tail
        body_map = _shifted(len(live), at, len(extras))
        body_map[idx] = -1  # piece 0 takes the index, but it is another body
        self._rebuild(live[:at] + extras + live[at:], body_map)
        if impact:
            self.tail += len(extras)
        self.last_fracture = results
        out, next_index = [], at
        for i, r in zip(idx, results):
            out.append(i)
            out.extend(range(next_index, next_index + len(r.bodies) - 1))
            next_index += len(r.bodies) - 1
        return out

    # ------------------------------------------------------------------ edits of the state
    def set_velocity(self, idx: list[int], linear=None, angular=None) -> None:
        self.wake(idx)
        b = self.buf.bodies
        for name, value in (("lin_vel", linear), ("ang_vel", angular)):
            if value is not None:
                v = finite_vector(value, name)
                field = getattr(b, name)
                arr = field.to_numpy()
                arr[idx] = v
                field.from_numpy(arr)

    def apply_impulse(self, idx: list[int], impulse, point=None) -> None:
        j = finite_vector(impulse, "impulse")
        self.wake(idx)
        b = self.buf.bodies
        v, w = b.lin_vel.to_numpy(), b.ang_vel.to_numpy()
        pos, rot, inv_i = b.pos.to_numpy(), b.rot.to_numpy(), b.inv_inertia.to_numpy()
        inv_m = b.inv_mass.to_numpy()
        for i in idx:
            v[i] += inv_m[i] * j
            if point is not None:
                r = quat_to_matrix(rot[i].astype(np.float64))
                arm = finite_vector(point, "point") - pos[i]
                w[i] += (r @ inv_i[i] @ r.T) @ np.cross(arm, j)
        b.lin_vel.from_numpy(v)
        b.ang_vel.from_numpy(w)

    # ------------------------------------------------------------------ impact breaks
    def _update_breakable(self) -> None:
        """Strength per body (inf: not breakable); the impact monitor runs only when one is finite."""
        self._strength = np.array([b.strength if b.breakable and not b.static else np.inf for b in self.bodies],
                                  dtype=np.float64)
        self.watch_impacts = bool(np.isfinite(self._strength).any())

    def impact_impulses(self) -> np.ndarray:
        """Largest manifold impulse [N s] each body took in the last step (zeros when unwatched)."""
        if not self.watch_impacts:
            return np.zeros(self.body_count)
        return self.buf.impacts.body_max.to_numpy()[: self.body_count].astype(np.float64)

    def note_breaks(self) -> None:
        """After a watched step: the bodies whose peak impulse passed their strength."""
        peak = self.buf.impacts.body_max.to_numpy()[: self.body_count]
        self._breaking = [int(i) for i in np.flatnonzero(peak > self._strength)]

    def take_breaks(self, step: int, dt: float) -> list[EventSpec]:
        """The impact fractures of the bodies that broke in the last step, as events to apply
        (and log) now; the list of broken bodies is emptied."""
        broken, self._breaking = self._breaking, []
        return [EventSpec(time=step * dt, kind="fracture", bodies=[i], pieces=int(self.bodies[i].pieces),
                          seed=int(step), outward_impulse=0.0, cause="impact") for i in broken]

    def keep_whole(self, i: int) -> None:
        """Body i could not fracture on impact: it stays whole and stops being breakable."""
        self.bodies[i] = dataclasses.replace(self.bodies[i], breakable=False)
        self._update_breakable()


def _shifted(count: int, at: int, inserted: int) -> np.ndarray:
    """Old body index -> new when ``inserted`` bodies go in at ``at`` (the static carrier, index
    ``count``, moves up with the rest)."""
    old = np.arange(count + 1)
    return np.where(old < at, old, old + inserted)


def _union_kinds(a, b) -> tuple:
    return tuple(sorted(set(a) | set(b)))


def _fracture_reserve(scene: Scene) -> int:
    """Pieces the scene may create: every breakable body's, and every fracture event's."""
    bodies = scene.bodies
    total = sum(piece_count(b, b.pieces) for b in bodies if b.breakable and not b.static)
    for event in scene.events:
        if event.kind == "fracture":
            total += sum(piece_count(bodies[i], event.pieces) if i < len(bodies) else event.pieces
                         for i in event.bodies)
    return total


def dropped_spread(bodies: list, dropped: list) -> float:
    """[1] The mass spread of a scene's dynamic bodies with the ones its drops add (1 without drops)."""
    if not dropped:
        return 1.0
    return mass_spread(np.asarray([1.0 / b.mass for b in list(bodies) + list(dropped) if not b.static]))


def finite_vector(value, what: str) -> np.ndarray:
    """Three finite numbers as float64, or SandboxError naming ``what``."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raw = np.asarray(None)
    has_bool = isinstance(value, (list, tuple)) and any(isinstance(x, (bool, np.bool_)) for x in value)
    if raw.shape != (3,) or raw.dtype.kind not in "iuf" or has_bool:
        raise SandboxError(f"{what} must be three numbers, got {value!r}")
    v = raw.astype(np.float64)
    if not np.all(np.isfinite(v)):
        raise SandboxError(f"{what} must be finite, got {value!r}")
    return v
