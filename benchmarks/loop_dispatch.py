"""What a Taichi loop costs on the CPU beyond its work: parallel, serialized, and a team barrier.

    python benchmarks/loop_dispatch.py [--items 1000] [--repeats 300]

Three kernels of ten trivial loops each over ``--items`` elements: top-level parallel loops
(each a dispatch to Taichi's thread pool, whose workers sleep between loops), the same loops
serialized (run on the launching thread), and one launch in which the threads form a team
(sandbox/solvers/team.py) and meet at the end of each of the ten loops. Prints the median
microseconds per loop. This is why the sandbox serializes light loops on the CPU
(``backend.serialize_light_loops``) and shares the iteration loop in one launch
(``Settings.iteration_launch = "shared"``).
"""

import argparse
import time

import numpy as np
import taichi as ti

LOOPS = 10


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--items", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=300)
    a = ap.parse_args()
    from sandbox import backend
    from sandbox.solvers import team as tm

    backend.init("cpu")
    x = ti.field(ti.f32, a.items)
    members = tm.cpu_threads()
    team = tm.team_for(LOOPS, members)

    @ti.kernel
    def parallel(n: ti.i32):
        for _ in ti.static(range(LOOPS)):
            for i in range(n):
                x[i] += 1.0

    @ti.kernel
    def serialized(n: ti.i32):
        for _ in ti.static(range(LOOPS)):
            ti.loop_config(serialize=True)
            for i in range(n):
                x[i] += 1.0

    @ti.kernel
    def shared(n: ti.i32, members: ti.i32):
        tm.reset_loop(team, LOOPS * members)
        for t in range(members * tm.TASK_ITEMS):
            if t % tm.TASK_ITEMS == 0:
                for p in range(LOOPS):
                    lo, hi, j = tm.next_chunk(team, p, n, t // tm.TASK_ITEMS, members, 0)
                    while lo < hi:
                        for i in range(lo, hi):
                            x[i] += 1.0
                        tm.finish(team, p, hi - lo)
                        lo, hi, j = tm.next_chunk(team, p, n, t // tm.TASK_ITEMS, members, j)
                    tm.wait(team, p, n)

    runs = {"parallel loops": lambda: parallel(a.items), "serialized loops": lambda: serialized(a.items),
            "team, one launch": lambda: shared(a.items, members)}
    for run in runs.values():
        run()
    ti.sync()
    times = {name: [] for name in runs}
    for _ in range(a.repeats):
        for name, run in runs.items():
            t = time.perf_counter()
            run()
            ti.sync()
            times[name].append(time.perf_counter() - t)
    print(f"{LOOPS} loops of {a.items} items, {members} Taichi threads, median of {a.repeats} launches")
    for name, ts in times.items():
        print(f"  {name:18s} {1e6 * np.median(ts) / LOOPS:8.1f} us per loop (launch included)")


if __name__ == "__main__":
    main()
