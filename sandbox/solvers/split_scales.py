"""How much of a body a contact block sees under mass splitting (mass_splitting.py): its
inverse-mass scale inside the block and the weight of its change in the body's merge.

A body's blocks counted in n_b (``rows.counted``) share one split; when it also has blocks left
out of the count (a gap that did not look like closing this step), those take a split of their
own, so that one acting anyway keeps the convergence proof (Settings.idle_split). Written once
for the rows' responses (rows.respond_row) and the sweep's merge (mass_splitting.sweep_block).
"""

import taichi as ti


@ti.func
def block_scales(s: ti.template(), rows: ti.template(), q: ti.i32, a: ti.i32, b: ti.i32):
    """The inverse-mass scales of bodies a and b inside the block of point q (``s``: the schedule's
    block_adjacency.BlockScratch): the body's split for a block counted in n_b, its idle split for
    one that is not (Settings.idle_split)."""
    sa, sb = s.scale[a], s.scale[b]
    if rows.counted[q] == 0:
        sa, sb = s.scale_idle[a], s.scale_idle[b]
    return sa, sb


@ti.func
def block_weights(s: ti.template(), rows: ti.template(), q: ti.i32, a: ti.i32, b: ti.i32):
    """1 / block_scales: how much of a block's change of its copies reaches each body."""
    wa, wb = s.weight[a], s.weight[b]
    if rows.counted[q] == 0:
        wa, wb = 1.0 / s.scale_idle[a], 1.0 / s.scale_idle[b]
    return wa, wb
