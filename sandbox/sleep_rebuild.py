"""A sleeping world across a rebuild of its buffers (edits.py): the sleep state and the sleeping
shapes' stored records read to the host, then installed again under the bodies' and shapes' new
indices."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sleep import AWAKE_ISLANDS, buffers_of, note_grid, restart_after_rebuild


@dataclass
class SleepSnapshot:
    """A sleeping world's state on the host, across a rebuild of its buffers (edits.py)."""

    asleep: np.ndarray  # (bodies,) bool
    timer: np.ndarray  # (bodies,) [s]
    label: np.ndarray  # (bodies,) island labels (body indices)
    records: dict  # the store's records of the sleeping shapes (SleepStore.read)
    awake_islands: int


def snapshot(buf, n_bodies: int, shape_body: np.ndarray) -> SleepSnapshot:
    """``shape_body``: each shape's body, to keep only the sleeping shapes' records."""
    sl = buf.sleep
    asleep = sl.asleep.to_numpy()[:n_bodies].astype(bool)
    records = sl.store.read()
    shape_body = np.asarray(shape_body, np.int64)
    for kind in ("point", "pair"):
        owner = records[kind + "_owner"]
        keep = owner < len(shape_body)  # a pooled buffer's ranges past this world's shapes are stale
        keep[keep] = asleep[shape_body[owner[keep]]]
        for key in _record_keys(records, kind):
            records[key] = records[key][keep]
    return SleepSnapshot(asleep, sl.timer.to_numpy()[:n_bodies], sl.islands.label.to_numpy()[:n_bodies], records,
                         int(sl.status[AWAKE_ISLANDS]))


def restore(buf, snap: SleepSnapshot, body_map: np.ndarray, shape_map: np.ndarray, margin: float) -> None:
    """Install a snapshot in (possibly new) buffers, old body i becoming body ``body_map[i]``
    and old shape s shape ``shape_map[s]`` (-1: gone). A sleeping body whose island label
    is gone wakes (an edit that removes a body wakes its island first, so this is a guard)."""
    sl = buffers_of(buf)
    n_new = int(buf.bodies.count[None])
    kept = body_map >= 0
    asleep = np.zeros(n_new, bool)
    timer = np.zeros(n_new, np.float32)
    label = np.full(n_new, -1, np.int32)
    old_label = snap.label.astype(np.int64)
    new_label = np.where(old_label >= 0, body_map[np.clip(old_label, 0, None)], -1)
    asleep[body_map[kept]] = snap.asleep[kept] & (new_label[kept] >= 0)
    timer[body_map[kept]] = snap.timer[kept]
    label[body_map[kept]] = new_label[kept]
    records = _remap_records(snap.records, shape_map)
    body_of = _new_shape_bodies(buf)
    for kind in ("point", "pair"):
        keep = asleep[body_of[records[kind + "_owner"]]]
        for key in _record_keys(records, kind):
            records[key] = records[key][keep]
    sl.store.write(records)
    for field, values in ((sl.asleep, asleep.astype(np.int32)), (sl.timer, timer), (sl.islands.label, label)):
        full = field.to_numpy()
        full[:n_new] = values
        field.from_numpy(full)
    restart_after_rebuild(sl, buf.shapes, buf.bodies, buf.bp, buf.errors, margin)
    # a snapshot is taken only of a world that sleeps (edits.Edits._sleep_snapshot). New buffers
    # start with resting 0, which labels no island: the next step counted no awake island, so
    # the stepper took every later step as idle and a world whose buffers grew froze mid-fall
    sl.resting[None] = 1
    sl.status[AWAKE_ISLANDS] = snap.awake_islands
    note_grid(sl)


def _remap_records(records: dict, shape_map: np.ndarray) -> dict:
    out = remap_owned(records, "point", shape_map)
    out.update(remap_owned(records, "pair", shape_map))
    return out


def remap_owned(records: dict, kind: str, shape_map: np.ndarray) -> dict:
    """One kind of record ("point": history, "pair": manifolds) with its owners and partners
    at the new shape ids, dropping records of shapes that are gone, then sorted by owner
    (stable, so each shape keeps its records' order)."""
    partner_key = kind + "_partner"
    owner = shape_map[records[kind + "_owner"].astype(np.int64)]
    partner = records[partner_key].astype(np.int64)
    moved = np.where(partner >= 0, shape_map[np.clip(partner, 0, None)], partner)  # planes: -1 - index
    keep = (owner >= 0) & ((partner < 0) | (moved >= 0))
    order = np.argsort(owner[keep], kind="stable")
    out = {key: records[key][keep][order] for key in _record_keys(records, kind)}
    out[kind + "_owner"] = owner[keep][order]
    out[partner_key] = moved[keep][order].astype(np.int32)
    return out


def _record_keys(records: dict, kind: str) -> list[str]:
    """The arrays of one kind of record: "point" (history) or "pair" (manifolds, with their slots)."""
    return [k for k in records if k.startswith(kind + "_") or (kind == "pair" and k.startswith("slot_"))]


def _new_shape_bodies(buf) -> np.ndarray:
    return buf.shapes.body.to_numpy()[: int(buf.shapes.count[None])].astype(np.int64)


def shape_map_for(old_shape_body: np.ndarray, new_shape_body: np.ndarray, body_map: np.ndarray,
                  new_body_count: int) -> np.ndarray:
    """Old shape id -> new shape id (-1: its body is gone). A world's shapes are laid out body
    by body in body order, then the mesh triangles on the static carrier (build.py), so a
    shape keeps its place within its body's run."""
    old_shape_body = np.asarray(old_shape_body, np.int64)
    new_shape_body = np.asarray(new_shape_body, np.int64)
    if len(old_shape_body) == 0:
        return np.zeros(0, np.int64)
    old_start = np.searchsorted(old_shape_body, np.arange(len(body_map)))
    new_start = np.searchsorted(new_shape_body, np.arange(new_body_count))
    local = np.arange(len(old_shape_body)) - old_start[old_shape_body]
    target = body_map[old_shape_body]
    return np.where(target >= 0, new_start[np.clip(target, 0, None)] + local, -1)
