"""Impact monitor for breakable bodies: the largest contact impulse each body took in a step.

A breakable body breaks when one contact manifold (the points of one touching
shape pair) passes it a total normal impulse above its ``strength`` [N s] within
one step. The impulse a point applies during a substep is its accumulated ``lam``
at the end of that substep (warm start, biased sweep and relax all add to it), so
the step's impulse is the sum over the substeps, which the iteration loop keeps in
``rows.lam_step`` while impulses are tracked (solvers/rows.py); ``reduce_manifolds``
sums each manifold's points in order (serially, so the sum is deterministic) and keeps
the per-body maximum with an atomic max, which does not depend on the order of the
updates either. A resting body of mass m passes about m g dt per step to its support;
an impact passes its whole momentum change in a step or two, so ``strength`` sits
between the two. The restitution pass is not counted (it runs after the reduction).

Worlds without breakable bodies never launch these kernels (house rule 8: what a
scene does not use costs nothing); the fields are allocated with the pool.
"""


import taichi as ti


@ti.data_oriented
class ImpactMonitor:
    def __init__(self, point_capacity: int, body_capacity: int):
        self.body_max = ti.field(ti.f32, max(16, body_capacity))  # [N s] largest manifold total, per body


@ti.kernel
def clear_bodies(m: ti.template(), bodies: ti.template()):
    for i in range(bodies.count[None]):
        m.body_max[i] = 0.0


@ti.kernel
def reduce_manifolds(m: ti.template(), c: ti.template(), rows: ti.template()):
    """Each manifold's normal impulse over the step (``rows.lam_step``, summed over the
    substeps while impulses are tracked), kept as the peak of both its bodies."""
    for k in range(c.manifold_count[None]):
        total = 0.0
        for j in range(c.m_start[k], c.m_start[k] + c.m_count[k]):
            total += rows.lam_step[j][0]
        ti.atomic_max(m.body_max[c.m_body_a[k]], total)
        ti.atomic_max(m.body_max[c.m_body_b[k]], total)
