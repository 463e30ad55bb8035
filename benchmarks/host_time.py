"""How much of a step is Python on the host, and how much is its kernels' launches.

    python benchmarks/host_time.py [--scenes stack_20,pyramid_20,pile_1000] [--iterations 15]
                                   [--settle 100] [--steps 300] [--rounds 3]

Builds each scene's world (CPU, mass splitting), steps it ``--settle`` times, then times
``--steps`` steps ``--rounds`` times, with a clock around every launch a step makes: the step
kernels' direct launches (repeat_launch.RepeatedKernel, where the tree has it) and any launch
through Taichi's own ``Kernel.launch_kernel`` (a first call, a ``to_numpy``, an event's kernels).
On the CPU a launch returns when its kernel has run, so "launches" is the kernels, their
runtime and the little Python inside a launch (placing new fields, filling the launch context),
and "Python" is everything else a step does on the host: the stepper's decisions, Taichi's
per-call key work and the host reads (an accessor read, host_counters.py, is not a launch
here). A diagnostic of the running code (it wraps Taichi's and the sandbox's launch methods in
this process; it runs on trees from before repeat_launch too); figures in docs/bench.md,
"Twenty-second pass".
"""

import argparse
import time

import taichi as ti
from taichi.lang import kernel_impl

from sandbox import Scene, World, backend
from sandbox.scene.library import resolve_scene

try:
    from sandbox.repeat_launch import RepeatedKernel
except ImportError:  # a tree from before it: every launch goes through Taichi's
    RepeatedKernel = None


class LaunchClock:
    """Seconds spent inside launches since the last ``reset`` (both launch paths wrapped)."""

    def __init__(self):
        self.seconds = 0.0
        self.launches = 0
        if RepeatedKernel is not None:
            self._wrap(RepeatedKernel, "_launch")
        self._wrap(kernel_impl.Kernel, "launch_kernel")

    def _wrap(self, cls, name: str) -> None:
        original = getattr(cls, name)
        clock = self

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                clock.seconds += time.perf_counter() - start
                clock.launches += 1

        setattr(cls, name, timed)

    def reset(self) -> None:
        self.seconds, self.launches = 0.0, 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="stack_20,pyramid_20,pile_1000")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--settle", type=int, default=100)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    backend.init("cpu")
    from sandbox.cpu_workers import cpu_threads

    clock = LaunchClock()
    print(f"# mass splitting, {a.iterations} iterations, {cpu_threads()} Taichi CPU thread(s); "
          f"us a step over {a.steps} steps, each round")
    for name in a.scenes.split(","):
        world = World(Scene.load(resolve_scene(name)), solver="mass-splitting", iterations=a.iterations, arch="cpu")
        world.step(a.settle)
        ti.sync()
        for r in range(a.rounds):
            clock.reset()
            start = time.perf_counter()
            world.step(a.steps)
            ti.sync()
            wall = (time.perf_counter() - start) / a.steps
            inside = clock.seconds / a.steps
            print(f"{name:<12} round {r + 1}: step {wall * 1e6:8.1f}  launches {inside * 1e6:8.1f} "
                  f"({clock.launches / a.steps:.1f} a step)  Python {(wall - inside) * 1e6:6.1f}")
        world.close()


if __name__ == "__main__":
    main()
