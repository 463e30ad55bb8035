"""Per-step diagnostics computed in kernels: energy, penetration, LCP residual.

Besides, the bodies awake and asleep and the islands (islands.py, sleep.py): a sleeping world
counts them in its step; any other world labels its islands here, on demand (a diagnostic: no
step of a world without the sleeping effect runs that kernel).

Definitions follow method.md section 3: kinetic energy sum(1/2 m v^2 + 1/2 w.Iw)
[J]; penetration max(0, -separation) over this step's contact points [m] (the
points found at the start of the step, as the anchor engines report them); the
natural-map residual of the velocity-level LCP over all rows, normal rows
|min(J_n u + b_n, K_nn lambda_n)| and friction rows the distance of lambda_t from
its projected gradient step, reported as RMS and max [m/s]. On the CPU the sums run in
index order on one thread (``serialize_light_loops``), so a state's metrics are the same
bits at every read: as parallel float atomics, 30 reads of one 1000-box state gave 14
different triples (tests/test_metrics.py). A GPU keeps the atomics, whose order,
and so the sums' last bits, vary; they never feed back into the simulation.
"""

import numpy as np
import taichi as ti

from .backend import serialize_light_loops
from .math3d import dot, mat_vec, quat_rotate_inv

KE, MAX_PEN, SUM_PEN, RES_SQ_SUM, RES_MAX_SQ = range(5)


@ti.data_oriented
class MetricBuffer:
    def __init__(self):
        self.values = ti.field(ti.f32, 8)


@ti.kernel
def compute_metrics(out: ti.template(), bodies: ti.template(), c: ti.template(), rows: ti.template()):
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for k in range(8):
        out.values[k] = 0.0
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for i in range(bodies.count[None]):
        if bodies.inv_mass[i] > 0.0:
            v = bodies.lin_vel[i]
            w = quat_rotate_inv(bodies.rot[i], bodies.ang_vel[i])
            ke = 0.5 * v.norm_sqr() / bodies.inv_mass[i] + 0.5 * dot(w, mat_vec(bodies.inertia[i], w))
            ti.atomic_add(out.values[KE], ke)
    ti.loop_config(serialize=ti.static(serialize_light_loops()))
    for q in range(c.count[None]):
        pen = ti.max(-c.sep[q], 0.0)
        ti.atomic_max(out.values[MAX_PEN], pen)
        ti.atomic_add(out.values[SUM_PEN], pen)
        r = rows.residual[q]
        ti.atomic_add(out.values[RES_SQ_SUM], r)
        ti.atomic_max(out.values[RES_MAX_SQ], r)


def read_metrics(b) -> dict:
    """This step's diagnostics of a world's buffers (``b``: buffers.BufferSet) as numbers.
    The residual is that of ``rows.residual`` as last computed (solvers/rows.compute_residuals)."""
    compute_metrics(b.metrics, b.bodies, b.contacts, b.rows)
    v = b.metrics.values.to_numpy().astype(np.float64)
    n = int(b.contacts.count[None])
    return {
        "kinetic_energy": float(v[KE]),
        "max_penetration": float(v[MAX_PEN]),
        "mean_penetration": float(v[SUM_PEN] / n) if n else 0.0,
        "contacts": n,
        "manifolds": int(b.contacts.manifold_count[None]),
        "manifolds_reused": int(b.manifold_cache.reused[None]),
        "pairs": int(min(b.bp.pair_total[None], b.bp.pair_capacity)),
        "pairs_reused": int(b.manifold_cache.reused_pairs[None]),
        "shapes_searched": int(b.bp.searched[None]),  # searched the grid for pairs; the others kept theirs
        "residual_rms": float(np.sqrt(v[RES_SQ_SUM] / (3 * n))) if n else 0.0,
        "residual_max": float(np.sqrt(v[RES_MAX_SQ])),
    }


def read_sleep_metrics(b, sleeping: bool, dynamic_count: int, awake) -> dict:
    """``awake_bodies``, ``sleeping_bodies`` (dynamic bodies) and ``islands`` (awake and asleep).
    ``awake``: the step's awake set (edits.Edits.awake_set), so that labelling the islands of a
    world that does not sleep reuses its kernels' instance."""
    from .islands import label_islands
    from .sleep import counts, islands_of

    if sleeping:
        c = counts(b)
    else:
        c = {"sleeping_bodies": 0, "islands": label_islands(islands_of(b), b.contacts, b.bodies, awake)}
    return {"awake_bodies": dynamic_count - c["sleeping_bodies"], **c}


def island_labels(b, sleeping: bool, n: int, static: np.ndarray, awake) -> np.ndarray:
    """Each body's island label (its smallest body index), -1 for static bodies."""
    from .islands import label_islands
    from .sleep import islands_of

    if not sleeping:
        label_islands(islands_of(b), b.contacts, b.bodies, awake)
    labels = islands_of(b).label.to_numpy()[:n].astype(np.int64)
    labels[static] = -1
    return labels
