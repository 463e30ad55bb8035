"""Which bodies and dynamic shapes a step visits: every one, or the awake ones of a sleeping world.

Every kernel loop over bodies or dynamic shapes takes a template argument ``awake``:

* ``EVERY`` in a world without the ``sleeping`` effect: the loops run over all bodies and over
  ``shapes.dynamic_ids`` exactly as they always did, and nothing of sleeping is compiled in
  (house rule 8: each choice of ``awake`` is its own kernel instance);
* a world's ``sleep.SleepBuffers`` with the effect on: compacted lists of the awake bodies
  and of their shapes, rebuilt with prefix sums only when an island falls asleep or wakes.
  A loop then runs over the awake items only, so a step's cost falls with the awake count
  (a flag test per sleeping item would still visit them all). A world that has slept keeps
  them when the effect goes off (``sleep.stop``: every body listed, no rest timers or
  islands), so that toggling sleeping never instantiates the step's kernels again.

A compacted set provides ``compact = True``, ``body_count`` / ``body_ids`` (awake dynamic
bodies, ascending) and ``shape_count`` / ``shape_ids`` (their shapes, in ``dynamic_ids``
order); ``ShapeList`` (shapes only) is enough for the loops that build a grid. Static
bodies are in no list: they never move, and every loop that visits them skips them anyway.
The pair search and the narrowphase of a sleeping world also read its sleeping shapes'
grid (``grid``) and mark touched islands (``note_touch``: ``asleep``, ``wake_mark``,
``touched`` and the island labels ``islands.label``), all provided by ``sleep.SleepBuffers``.
"""

import taichi as ti


class Everything:
    """The ``awake`` argument of a world that does not sleep: every body, every dynamic shape.
    A plain class for the launch cost (dispatch.LoopDispatch says why); ``EVERY`` is its one
    instance."""

    compact = False


EVERY = Everything()


@ti.data_oriented
class ShapeList:
    """A compacted list of dynamic shapes (``shape_ids[:shape_count]``)."""

    compact = True

    def __init__(self, shape_capacity: int):
        self.shape_count = ti.field(ti.i32, ())
        self.shape_ids = ti.field(ti.i32, max(1, shape_capacity))


@ti.func
def body_total(bodies: ti.template(), awake: ti.template()) -> ti.i32:
    """How many bodies a body loop visits (its range; ``body_id`` maps a position to a body). An
    expression, no local variable: a loop's range may call it without a statement before the loop
    (solvers/substep_loops.py)."""
    if ti.static(awake.compact):
        return awake.body_count[None]
    else:
        return bodies.count[None]


@ti.func
def body_id(awake: ti.template(), k: ti.i32) -> ti.i32:
    i = k
    if ti.static(awake.compact):
        i = awake.body_ids[k]
    return i


@ti.func
def shape_total(shapes: ti.template(), awake: ti.template()) -> ti.i32:
    """How many dynamic shapes a shape loop visits; position k is also the shape's broadphase
    slot (its pair counts and ranges are indexed by k)."""
    n = 0
    if ti.static(awake.compact):
        n = awake.shape_count[None]
    else:
        n = shapes.dynamic_count[None]
    return n


@ti.func
def shape_id(shapes: ti.template(), awake: ti.template(), k: ti.i32) -> ti.i32:
    i = 0
    if ti.static(awake.compact):
        i = awake.shape_ids[k]
    else:
        i = shapes.dynamic_ids[k]
    return i


@ti.func
def note_touch(awake: ti.template(), b: ti.i32):
    """The narrowphase found points between an awake shape and body b: if b sleeps, mark its
    island to wake (sleep.wake_touched wakes it and has the collision done again)."""
    if awake.asleep[b]:
        awake.wake_mark[awake.islands.label[b]] = 1
        ti.atomic_add(awake.touched[None], 1)
