"""How a step's heavy loops run on the CPU: on the launching thread, or shared by the worker threads.

Every top-level loop of a Taichi kernel is a parallel loop, and on the CPU each one is a
thread-pool dispatch: ~45 us on the 2-core VM whatever its length, an empty range included
(``benchmarks/loop_dispatch.py``). Light loops (copies, clears, scans) always run on the
launching thread (``backend.serialize_light_loops``). The heavy ones (pair search,
narrowphase, rows, contact store) are worth sharing only when there is enough of them.
Measured in one run (mass splitting; ``benchmarks/kernel_times.py``, unsynced ms/step, two
alternations each): run on the launching thread, the 20-box stack at 4 iterations went from
1.0-1.2 to 0.63 ms, the 150-body playground at 15 from 1.15-1.2 to 0.75, the 210-box pyramid
from 2.72 to 2.42-2.59, while the 1000-box pile went from 6.5-6.6 to 6.7-7.0 ms: the
crossover lies between 256 and 1024 bodies. A world picks its dispatch when its buffers are
sized, from its body capacity (a power of two), and passes it to the step's kernels as a
template argument (each choice is its own kernel instance, like ``awake``): a serial loop
visits the same items and each writes only its own slots, so both dispatches give the same
bits (tests/test_dispatch.py). CUDA always runs them in parallel.
"""

SERIAL_BODY_LIMIT = 512
"""A CPU world with at most this many bodies (its buffers' capacity) runs its heavy loops on
the launching thread."""


class LoopDispatch:
    """The ``dispatch`` template argument: ``serial`` is read at compile time by
    ``ti.loop_config(serialize=ti.static(dispatch.serial))`` before each heavy loop. A plain
    class, not ``ti.data_oriented``: Taichi keys a launch on its template arguments in Python,
    and every ``isinstance`` it tries on a data-oriented object goes through that decorator's
    slow ``__getattribute__`` (~7 look-ups per argument per launch); the two instances live as
    long as the module, so the strong reference Taichi then keeps costs nothing."""

    def __init__(self, serial: bool):
        self.serial = serial

    def __repr__(self) -> str:
        return "SERIAL" if self.serial else "PARALLEL"


SERIAL = LoopDispatch(True)
PARALLEL = LoopDispatch(False)


def dispatch_for(arch: str, body_capacity: int) -> LoopDispatch:
    """The dispatch of a world on ``arch`` whose buffers hold ``body_capacity`` bodies."""
    return SERIAL if arch == "cpu" and body_capacity <= SERIAL_BODY_LIMIT else PARALLEL
