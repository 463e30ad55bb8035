"""Contact persistence: carry last step's impulses to this step's points (warm starting).

Points of one shape are contiguous in the contact buffer (contacts.py), so the
old points of shape ``a`` are one short range ``[first, last)``. A new point
takes the impulse of the old point with the same partner and feature id; failing
that (clipping can rotate feature ids while the points stay put, see Newton's
``contact_match.py``), of the nearest old point of the same partner within
``Settings.match_distance``, compared in body a's frame. Tangent impulses are
kept as a world vector and re-projected on the new basis, so a rotating basis
does not kick resting stacks. No atomics: the result is deterministic.

An edit that rebuilds the world's buffers (edits.py) carries the history over on the host
(``read_history`` / ``write_history``, its shapes renumbered by sleep_rebuild.remap_owned): a
resting pile that starts a step with no impulses falls for a substep before its sweeps catch
up: adding one box 50 m from a resting pyramid_20 used to send its boxes to 0.29 m/s and dip
its top 12.8 mm (mass splitting, 15 iterations; docs/method-notes.md).
"""


import numpy as np
import taichi as ti

from .awake import shape_id, shape_total
from .backend import serialize_light_loops
from .field_upload import write_rows
from .math3d import dot

vec3 = ti.math.vec3

HISTORY_FIELDS = ("partner", "feature", "anchor", "lam_n", "lam_t")
"""A history record's fields, as ``read_history`` names them (``point_`` + field)."""


@ti.data_oriented
class ContactHistory:
    def __init__(self, capacity: int, shape_capacity: int):
        c = max(16, capacity)
        sc = max(1, shape_capacity)
        self.count = ti.field(ti.i32, ())
        self.partner = ti.field(ti.i32, c)
        self.feature = ti.field(ti.i32, c)
        self.anchor = ti.Vector.field(3, ti.f32, c)  # in body a's frame [m]
        self.lam_n = ti.field(ti.f32, c)
        self.lam_t = ti.Vector.field(3, ti.f32, c)  # world tangent impulse [N s]
        self.shape_first = ti.field(ti.i32, sc)
        self.shape_last = ti.field(ti.i32, sc)
        self.capacity = c


@ti.func
def clear_history_loops(hist: ti.template()):
    hist.count[None] = 0
    for i in range(hist.shape_first.shape[0]):
        hist.shape_first[i] = 0
        hist.shape_last[i] = 0


@ti.kernel
def clear_history(hist: ti.template()):
    clear_history_loops(hist)


@ti.func
def match_contact(hist: ti.template(), c: ti.template(), rows: ti.template(), match_distance: ti.f32,
                  warm_factor: ti.f32, q: ti.i32):
    """Point q inherits the impulse of last step's point of the same shape pair with its
    feature id, or else of the nearest within ``match_distance`` (anchors in body a's frame,
    ``rows.ra_body``: prepare_row runs first). ``warm_factor`` also converts the stored
    per-step impulse to this step's per-substep one."""
    i = c.shape_a[q]
    anchor = rows.ra_body[q]
    best = -1
    best_d2 = match_distance * match_distance
    exact = 0
    for o in range(hist.shape_first[i], hist.shape_last[i]):
        if exact == 0 and hist.partner[o] == c.partner[q]:
            if hist.feature[o] == c.feature[q]:
                best = o
                exact = 1
            else:
                d2 = (hist.anchor[o] - anchor).norm_sqr()
                if d2 < best_d2:
                    best_d2 = d2
                    best = o
    lam = vec3(0.0)
    if best >= 0:
        lt = hist.lam_t[best]
        lam = warm_factor * vec3(hist.lam_n[best], dot(lt, rows.t1[q]), dot(lt, rows.t2[q]))
    rows.lam[q] = lam


@ti.func
def match_contacts_loops(hist: ti.template(), c: ti.template(), rows: ti.template(), match_distance: ti.f32,
                         warm_factor: ti.f32):
    for q in range(c.count[None]):
        match_contact(hist, c, rows, match_distance, warm_factor, q)


@ti.kernel
def match_contacts(hist: ti.template(), c: ti.template(), rows: ti.template(), match_distance: ti.f32,
                   warm_factor: ti.f32):
    match_contacts_loops(hist, c, rows, match_distance, warm_factor)


@ti.func
def store_contacts_loops(hist: ti.template(), c: ti.template(), rows: ti.template(), shapes: ti.template(),
                         substeps: ti.i32, awake: ti.template(), dispatch: ti.template()):
    """This step's impulses for the next step's warm start. ``awake`` (awake.py): the shapes
    whose contacts were found (a sleeping shape's impulses wait in sleep.py's store)."""
    n = ti.min(c.count[None], hist.capacity)
    hist.count[None] = n
    ti.loop_config(serialize=ti.static(dispatch.serial))
    for q in range(n):
        hist.partner[q] = c.partner[q]
        hist.feature[q] = c.feature[q]
        hist.anchor[q] = rows.ra_body[q]  # body a's frame at the pose the contact was found at
        lam = rows.lam[q] * ti.cast(substeps, ti.f32)  # per-substep impulse -> per step
        hist.lam_n[q] = lam[0]
        hist.lam_t[q] = rows.t1[q] * lam[1] + rows.t2[q] * lam[2]
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(hist.shape_first.shape[0]):
        hist.shape_first[i] = 0
        hist.shape_last[i] = 0
    n_shapes = shape_total(shapes, awake)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(n_shapes):
        i = shape_id(shapes, awake, k)
        hist.shape_first[i] = c.shape_first[i]
        hist.shape_last[i] = ti.min(c.shape_last[i], n)


@ti.kernel
def store_contacts(hist: ti.template(), c: ti.template(), rows: ti.template(), shapes: ti.template(),
                   substeps: ti.i32, awake: ti.template(), dispatch: ti.template()):
    store_contacts_loops(hist, c, rows, shapes, substeps, awake, dispatch)


def owned_rows(first: np.ndarray, last: np.ndarray):
    """(record rows, owner of each row) of per-shape ranges [first, last)."""
    sizes = np.maximum(last - first, 0)
    owner = np.repeat(np.arange(len(first)), sizes)
    starts = np.repeat(first, sizes)
    offsets = np.arange(len(owner)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return (starts + offsets).astype(np.int64), owner.astype(np.int64)


def read_history(hist: ContactHistory) -> dict:
    """The stored impulses as host arrays, with each record's owner shape (``point_owner``)."""
    rows, owner = owned_rows(hist.shape_first.to_numpy(), hist.shape_last.to_numpy())
    rows, owner = rows[rows < hist.count[None]], owner[rows < hist.count[None]]
    out = {"point_owner": owner}
    for name in HISTORY_FIELDS:
        out["point_" + name] = getattr(hist, name).to_numpy()[rows]
    return out


def write_history(hist: ContactHistory, records: dict) -> None:
    """Install ``read_history``'s records (owners sorted ascending, ids already renumbered); a
    history too small for them starts empty, as a rebuilt world did before."""
    owner = records["point_owner"]
    n = len(owner) if len(owner) <= hist.capacity else 0
    shapes = np.arange(hist.shape_first.shape[0])
    write_rows([(hist.shape_first, 0, np.searchsorted(owner[:n], shapes, side="left")),
                (hist.shape_last, 0, np.searchsorted(owner[:n], shapes, side="right"))]
               + [(getattr(hist, name), 0, records["point_" + name][:n]) for name in HISTORY_FIELDS])
    hist.count[None] = n
