"""The scene timeline: ``[[event]]`` entries -> ``EventSpec``s, replayed once at load time.

Each event has a ``time`` [s] and a ``kind``:

* ``drop``: new bodies, described exactly like a ``rain`` generator (the loader's
  rain reader expands them, seeded), appended to the body list when it applies;
* ``set_velocity``: new linear and/or angular velocity of some bodies;
* ``impulse``: a linear impulse [N s] on some bodies, at their centre of mass or a world point;
* ``remove``: bodies leave the world (later bodies move down to close the gap);
* ``solver``: switch to another solver (with the ``[solver]`` table's validation and options);
* ``iterations``: change the solver's iteration count;
* ``gravity``: a new gravity vector (``gravity = [0, 0, 0]`` switches it off);
* ``effects``: the contact effects now on (``effects = ["friction"]``: restitution off);
* ``fracture``: bodies break into convex pieces (``fracture.py``): a compound into its
  shapes, a convex body into ``pieces`` Voronoi cells (seed ``seed`` + k for the k-th
  listed body), pushed apart by a total outward ``impulse`` [N s]. Piece 0 takes the
  body's place in the body list, the other pieces are appended in listed order.
* ``formulation``: the time-stepping scheme, ``"soft-step"`` or ``"paper"``, and optionally the
  paper's ``baumgarte`` factor (sandbox/formulation.py).

The engine also applies ``timestep`` events (new dt and substeps), which only the web
sandbox issues: a scene file's event times are converted to steps with the scene's dt.

Events are sorted by time, stably (two events at the same time keep their file
order). Body references (``bodies = [...]``) are names or integer indices into
the body list *as it is when the event applies*: the scene's bodies in
``Scene.bodies`` order, then each drop's bodies appended in timeline order,
removals closing the gaps, each fracture's extra pieces appended. To check them, the loader replays the timeline here:
it tracks which bodies exist at each event, resolves every name to its index at
that moment and rejects references to bodies that do not exist yet, no longer
exist, are listed twice, or are static where the event would push them.
``EventSpec.bodies`` holds the resolved indices, so the engine never sees a name.

This module only resolves; reading the drop and solver fields is the loader's
(``read_drop``, ``read_solver`` are passed in, so the two share one schema).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..settings import FORMULATIONS
from .schema import Reader
from .spec import DEFAULT_PIECES, MAX_PIECES, BodySpec, EventSpec, ShapeSpec

EVENT_KINDS = ("drop", "set_velocity", "impulse", "remove", "solver", "iterations", "gravity", "effects",
               "fracture", "formulation")
_PUSHED = ("static bodies cannot be pushed, so {a} {kind} event cannot target it (make the body dynamic, "
           "or remove it instead)")
STATIC_REFUSALS = {
    "set_velocity": _PUSHED,
    "impulse": _PUSHED,
    "fracture": "static bodies cannot be fractured (make the body dynamic)",
}
"""Events that cannot target static bodies, and why (the message's tail; ``{a} {kind}``: the event)."""
MAX_ITERATIONS = 1_000_000


@dataclass
class _Parsed:
    event: EventSpec
    reader: Reader
    refs: list = field(default_factory=list)  # raw body references, in file order


def read_events(readers: list[Reader], *, duration, bodies: list[BodySpec], mesh_names: set, event_keys: dict,
                read_drop, read_solver, read_effects, claim_name, budget: int) -> list[EventSpec]:
    """Parse, sort and replay the ``[[event]]`` entries; returns the sorted ``EventSpec``s.

    ``event_keys[kind]`` = (allowed keys, required keys); ``read_drop(r, budget)``
    returns the drop's BodySpecs; ``read_solver(r)`` returns (name, iterations or
    None, options); ``read_effects(r)`` returns the set of effects named by ``effects``; ``claim_name(name, r, key)`` rejects a name already in use.
    """
    parsed: list[_Parsed] = []
    drops_by_name: dict[str, _Parsed] = {}
    for r in readers:
        kind = r.string("kind", choices=EVENT_KINDS, what="event kind")
        allowed, required = event_keys[kind]
        r.check_keys(allowed, required=required, what=f"{_article(kind)} '{kind}' event")
        time = r.real("time", nonnegative=True)
        if duration is not None and time > duration:
            raise r.error(f"event time {time:g} s is after the scene's duration {duration:g} s ([world] duration); "
                          "move the event or lengthen the duration", "time")
        item = _Parsed(EventSpec(time=time, kind=kind), r)
        ev = item.event
        if kind == "drop":
            ev.new_bodies = read_drop(r, budget)
            budget -= len(ev.new_bodies)
            for body in ev.new_bodies:
                claim_name(body.name, r, "name")
                if body.name is not None:
                    drops_by_name[body.name] = item
        elif kind in ("set_velocity", "impulse", "remove", "fracture"):
            item.refs = _read_references(r)
            if kind == "set_velocity":
                ev.linear_velocity = r.vector("linear_velocity", 3, None)
                ev.angular_velocity = r.vector("angular_velocity", 3, None)
                if ev.linear_velocity is None and ev.angular_velocity is None:
                    raise r.error("a set_velocity event needs 'linear_velocity', 'angular_velocity' or both",
                                  "linear_velocity")
            elif kind == "impulse":
                ev.impulse = r.vector("impulse", 3)
                ev.point = r.vector("point", 3, None)
            elif kind == "fracture":
                ev.pieces = r.integer("pieces", DEFAULT_PIECES, minimum=2, maximum=MAX_PIECES)
                ev.seed = r.integer("seed", 0, minimum=0, maximum=2**31 - 1)
                ev.outward_impulse = r.real("impulse", 0.0, nonnegative=True)
        elif kind == "solver":
            ev.solver, ev.iterations, ev.options = read_solver(r)
        elif kind == "gravity":
            ev.gravity = r.vector("gravity", 3)
        elif kind == "effects":
            ev.effects = tuple(sorted(read_effects(r)))
        elif kind == "formulation":
            ev.formulation = r.string("formulation", choices=FORMULATIONS, what="formulation")
            ev.baumgarte = r.real("baumgarte", None, low=0.0, high=1.0, open_high=True)
        else:  # iterations
            ev.iterations = r.integer("iterations", minimum=1, maximum=MAX_ITERATIONS)
        parsed.append(item)
    order = sorted(range(len(parsed)), key=lambda i: parsed[i].event.time)  # stable: ties keep file order
    _replay([parsed[i] for i in order], bodies, mesh_names, drops_by_name)
    return [parsed[i].event for i in order]


def _read_references(r: Reader) -> list:
    """``bodies``: a non-empty list of names (strings) and indices (integers >= 0)."""
    items = r.items("bodies")
    if not items:
        raise r.error("expected a non-empty list of body names or indices", "bodies")
    refs = []
    for j, item in enumerate(items):
        key = f"bodies[{j}]"
        if isinstance(item, str):
            if not item:
                raise r.error("a body name must not be empty", key)
            refs.append(item)
        elif isinstance(item, (int, np.integer)) and not isinstance(item, (bool, np.bool_)):
            refs.append(r.integer_value(item, key, minimum=0))
        else:
            raise r.error(f"expected a body name (string) or index (integer >= 0), got {item!r}", key)
    return refs


def _replay(events: list[_Parsed], bodies: list[BodySpec], mesh_names: set, drops_by_name: dict) -> None:
    """Walk the sorted timeline, tracking the live body list; fill each ``EventSpec.bodies``."""
    every = list(bodies)  # every body ever created, by id (scene bodies, then drops as they apply)
    live = list(range(len(bodies)))  # ids of the bodies that exist now, in body-list order
    index_of: dict | None = None  # id -> current index, rebuilt after the list changes
    by_name = {b.name: i for i, b in enumerate(bodies) if b.name is not None}
    removed: dict[int, _Parsed] = {}
    for item in events:
        ev, r = item.event, item.reader
        if ev.kind == "drop":
            for body in ev.new_bodies:
                if body.name is not None:
                    by_name[body.name] = len(every)
                live.append(len(every))
                every.append(body)
            index_of = None
            continue
        if not item.refs:
            continue
        if index_of is None:
            index_of = {gid: i for i, gid in enumerate(live)}
        seen: dict[int, int] = {}
        resolved = []
        for j, ref in enumerate(item.refs):
            key = f"bodies[{j}]"
            gid = _resolve(ref, key, ev, r, live, by_name, removed, mesh_names, drops_by_name)
            label = _label(ref, gid, every)
            if gid in seen:
                raise r.error(f"{label} is listed twice (also as bodies[{seen[gid]}])", key)
            seen[gid] = j
            if ev.kind in STATIC_REFUSALS and every[gid].static:
                why = STATIC_REFUSALS[ev.kind].format(a=_article(ev.kind), kind=ev.kind)
                raise r.error(f"{label} is static: {why}", key)
            resolved.append(index_of[gid])
        ev.bodies = resolved
        if ev.kind == "fracture":
            for gid in seen:  # listed order: piece 0 takes the body's slot, the others are appended
                removed[gid] = item
                body = every[gid]
                count = len(body.shapes) if len(body.shapes) >= 2 else ev.pieces
                pieces = [_piece_placeholder() for _ in range(count)]
                live[live.index(gid)] = len(every)
                every.append(pieces[0])
                for piece in pieces[1:]:
                    live.append(len(every))
                    every.append(piece)
            index_of = None
        if ev.kind == "remove":
            gone = set(seen)
            for gid in gone:
                removed[gid] = item
            live = [gid for gid in live if gid not in gone]
            index_of = None


def _resolve(ref, key, ev: EventSpec, r: Reader, live, by_name, removed, mesh_names, drops_by_name) -> int:
    at = f"at t = {ev.time:g} s"
    if isinstance(ref, int):
        if ref >= len(live):
            raise r.error(f"body index {ref} does not exist {at}: the body list then has {len(live)} bodies "
                          f"(indices 0..{len(live) - 1})" if live else
                          f"body index {ref} does not exist {at}: no bodies exist then", key)
        return live[ref]
    if ref in by_name:
        gid = by_name[ref]
        if gid in removed:
            gone = removed[gid]
            verb = "fractured" if gone.event.kind == "fracture" else "removed"
            raise r.error(f"body {ref!r} does not exist {at}: {gone.reader.entry} {verb} it at "
                          f"t = {gone.event.time:g} s", key)
        return gid
    if ref in drops_by_name:
        drop = drops_by_name[ref]
        raise r.error(f"body {ref!r} does not exist yet {at}: {drop.reader.entry} drops it at "
                      f"t = {drop.event.time:g} s (events apply in time order, ties in file order)", key)
    if ref in mesh_names:
        raise r.error(f"{ref!r} is a static mesh, not a body; events act on bodies only", key)
    raise r.error(f"no body named {ref!r} (names come from [[body]], [[generate]] and [[static]] entries and "
                  "from drop events' name prefixes: <prefix>_0, <prefix>_1, ...)", key)


def _piece_placeholder() -> BodySpec:
    """A fracture piece as the replay sees it: one dynamic convex shape, no name."""
    return BodySpec(shapes=[ShapeSpec("hull")], position=np.zeros(3))


def _label(ref, gid: int, every: list[BodySpec]) -> str:
    if isinstance(ref, str):
        return f"body {ref!r}"
    name = every[gid].name
    return f"body index {ref}" + (f" ({name!r})" if name else "")


def _article(word: str) -> str:
    return "an" if word[0] in "aeiou" else "a"
