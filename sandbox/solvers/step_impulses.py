"""The step's impulse per point (``Rows.lam_step``): each substep's impulses summed, then the
restitution pass's, when something reads them (restitution, breakable bodies,
``World.track_impulses``). Impulses are per substep (rows.py), so a step's is their sum."""

import taichi as ti


@ti.func
def add_step_impulse(rows: ti.template(), q: ti.i32):
    """After a substep: point q's impulses of that substep join the step's sum."""
    rows.lam_step[q] += rows.lam[q]


@ti.func
def add_step_impulses_loop(rows: ti.template(), c: ti.template()):
    for q in range(c.count[None]):
        add_step_impulse(rows, q)


@ti.kernel
def add_step_impulses(rows: ti.template(), c: ti.template()):
    add_step_impulses_loop(rows, c)


@ti.kernel
def add_bounces(rows: ti.template(), c: ti.template()):
    """After the restitution pass: its impulses join the step's sum (not the warm start)."""
    for q in range(c.count[None]):
        rows.lam_step[q][0] += rows.lam_bounce[q]
