"""A step's set-up, in the pieces both of its launches run: the fused set-up loop
(step_kernels.prepare_step_loops) and the team's set-up phases (team_loop._set_up_phases).

The set-up is one pass over the points (each point's rows and warm-start match, independent of
the others) and then one ordered pass over the blocks (the impact rows' list and the bodies'
adjacency, which read every point's rows). Kept here once, so that the two launches cannot
drift apart: they must give the same bits.
"""

import taichi as ti

from ..persistence import match_contact
from .block_adjacency import build_adjacency_loops
from .impact_carry import list_carry_rows
from .rows import prepare_row


@ti.func
def prepare_point(b: ti.template(), q: ti.i32, match_distance: ti.f32, warm_factor: ti.f32,
                  shares: ti.template()):
    """Point q's rows (rows.prepare_row; ``shares`` False: its response shares are left to the
    team's lane copy) and its warm-start impulses from last step's store."""
    prepare_row(b.rows, b.contacts, b.bodies, q, shares=shares)
    match_contact(b.history, b.contacts, b.rows, match_distance, warm_factor, q)


@ti.func
def order_blocks(b: ti.template(), blk: ti.template(), kind: ti.template(), mode: ti.template(), omega: ti.f32):
    """After every point's rows: the impact rows the folded warm start clamps, and the schedule's
    block adjacency (its split counts read the rows and the warm start). Their loops are ordered:
    a kernel's top level runs them on the launching thread (backend.serialize_light_loops), a
    team one member."""
    list_carry_rows(b.rows, b.contacts)
    build_adjacency_loops(blk, b.contacts, b.bodies, b.rows, kind, mode, omega)
