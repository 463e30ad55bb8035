"""Contact persistence: carry last step's impulses to this step's points (warm starting).

Points of one shape are contiguous in the contact buffer (contacts.py), so the
old points of shape ``a`` are one short range ``[first, last)``. A new point
takes the impulse of the old point with the same partner and feature id; failing
that (clipping can rotate feature ids while the points stay put, see Newton's
``contact_match.py``), of the nearest old point of the same partner within
``Settings.match_distance``, compared in body a's frame. Tangent impulses are
kept as a world vector and re-projected on the new basis, so a rotating basis
does not kick resting stacks. No atomics: the result is deterministic.
"""


import taichi as ti

from .awake import shape_id, shape_total
from .backend import serialize_light_loops

vec3 = ti.math.vec3


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


@ti.kernel
def clear_history(hist: ti.template()):
    hist.count[None] = 0
    for i in range(hist.shape_first.shape[0]):
        hist.shape_first[i] = 0
        hist.shape_last[i] = 0


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
        lam = warm_factor * vec3(hist.lam_n[best], lt.dot(rows.t1[q]), lt.dot(rows.t2[q]))
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
