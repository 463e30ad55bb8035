"""Light bodies under heavy ones: which blocks the Jacobi family sweeps again (Settings.ratio_sweeps).

A split sweep moves a heavy body's load into a light one a 1 / n_b share at a time, and the
stability limit of one sweep per substep (contact_spring.py) keeps the light body's springs
too soft to hold what rests on it: a 1000 kg box on 100, 10 and 1 kg boxes sank 61.5 mm at 8
iterations under mass splitting (docs/method-notes.md, "The 1:1000 column at 8 iterations").
So the lighter body of a touching pair of dynamic bodies whose masses differ
``Settings.ratio_mass``-fold or more is marked *light*; every block of a light body (its pairs
with the heavy body, the ground, its neighbours) is swept ``Settings.ratio_sweeps`` more times
per substep after the biased sweep, and under mass splitting and Jacobi its rows take a
stiffer stability limit, that of the sweeps they get (contact_spring.light_sweeps,
SolverInfo.stiffens_light_rows); under all three they take their own damping ratio
(Settings.light_damping_ratio).
The extra sweeps visit listed blocks and bodies only, so on the CPU a scene without such a pair
pays nothing and a pile with one small box under a big one pays for that box's blocks; a GPU's
per-substep launch runs their unrolled loops empty (substep_loops.py: five tasks a substep),
unless no two of the world's dynamic masses differ that much: then a GPU's launch compiles them
out (effects.py, ``light_bodies``; the CPU keeps its free empty loops rather than compile a second
set of iteration kernels).

The lists are filled with atomic counters, in no set order: each listed block writes its own
two slots and each listed body adds its slots in its adjacency's fixed order, so the order of
the lists changes no bit.
"""

import taichi as ti

from .contact_spring import RATIO_MASS, RATIO_SWEEPS



@ti.func
def reset_light_lists(s: ti.template()):
    """Empty lists and no extra sweep, before build_adjacency's loops fill them."""
    s.light_block_count[None] = 0
    s.light_body_count[None] = 0
    s.light_sweeps[None] = 0


@ti.func
def mark_light(s: ti.template(), rows: ti.template(), bodies: ti.template(), a: ti.i32, b: ti.i32):
    """Marks the lighter of two dynamic bodies a and b of a block that can act when the other is
    at least ``Settings.ratio_mass`` times heavier (a max: the same in any order)."""
    ia = bodies.inv_mass[a]
    ib = bodies.inv_mass[b]
    if rows.params[RATIO_SWEEPS] > 0.0 and ia > 0.0 and ib > 0.0:
        if ia >= rows.params[RATIO_MASS] * ib:
            ti.atomic_max(s.light[a], 1)
        elif ib >= rows.params[RATIO_MASS] * ia:
            ti.atomic_max(s.light[b], 1)


@ti.func
def light_pair(s: ti.template(), a: ti.i32, b: ti.i32) -> ti.i32:
    """1: a block or row of bodies a and b takes the extra sweeps (one of them is light)."""
    return s.light[a] | s.light[b]


@ti.func
def list_light_block(s: ti.template(), k: ti.i32, a: ti.i32, b: ti.i32):
    """Block k (bodies a and b) is listed for the extra sweeps when one of its bodies is light."""
    light = light_pair(s, a, b)
    s.block_light[k] = light
    if light:
        s.light_blocks[ti.atomic_add(s.light_block_count[None], 1)] = k


@ti.func
def list_light_body(s: ti.template(), rows: ti.template(), i: ti.i32):
    """Dynamic body i is listed when a listed block touches it; a light body sets this step's
    extra sweep count."""
    touched = 0
    for e in range(s.adj_start[i], s.adj_start[i + 1]):
        touched |= s.block_light[s.adj[e] // 2]
    if touched:
        s.light_bodies[ti.atomic_add(s.light_body_count[None], 1)] = i
    if s.light[i]:
        ti.atomic_max(s.light_sweeps[None], ti.cast(rows.params[RATIO_SWEEPS], ti.i32))
