"""Is ``sandbox bench --quick`` within its time budget (2 minutes on the 2-core CPU)?

    python benchmarks/bench_quick_budget.py [--cold] [--budget 120] [--out DIR]

Runs ``python -m sandbox bench --quick --quiet`` in a fresh process from the repository root
(so this checkout's ``sandbox`` is the one timed), prints its wall time and exits 1 when it is
over the budget (2 when the bench itself fails). ``--cold`` points Taichi's offline kernel cache
(``TI_OFFLINE_CACHE_FILE_PATH``) at a new, empty temporary directory, so every kernel is
compiled as on a fresh clone; without it the user's cache is used, as on a second run.

A budget is a property of a machine, not of the code's correctness, so it lives here rather
than in the test suite (tests/test_bench.py checks the outputs' shape and sense).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BUDGET_S = 120.0
"""[s] The promise of ``--quick`` (README, docs/bench.md) on the 2-core CPU."""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cold", action="store_true", help="start from an empty Taichi kernel cache")
    ap.add_argument("--budget", type=float, default=BUDGET_S, help=f"seconds (default {BUDGET_S:g})")
    ap.add_argument("--out", help="keep the bench outputs here (default: a temporary directory)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_quick_") as tmp:
        env = dict(os.environ)
        if a.cold:
            env["TI_OFFLINE_CACHE_FILE_PATH"] = str(Path(tmp) / "taichi_cache")
        out = a.out or str(Path(tmp) / "out")
        command = [sys.executable, "-m", "sandbox", "bench", "--quick", "--quiet", "--out", out]
        print(f"running    {' '.join(command[1:])}  ({'empty' if a.cold else 'existing'} Taichi kernel cache)",
              flush=True)
        t0 = time.perf_counter()
        rc = subprocess.run(command, cwd=REPO, env=env).returncode
        wall = time.perf_counter() - t0
        if a.cold:  # evidence that Taichi compiled into the empty cache rather than reading another one
            cached = [f for f in Path(env["TI_OFFLINE_CACHE_FILE_PATH"]).rglob("*") if f.is_file()]
            print(f"cache      {len(cached)} files compiled into the empty kernel cache")
    print(f"wall time  {wall:.1f} s (budget {a.budget:g} s, {os.cpu_count()} CPUs)")
    if rc != 0:
        print(f"FAILED     sandbox bench --quick exited with {rc}")
        return 2
    if wall > a.budget:
        print(f"OVER       by {wall - a.budget:.1f} s")
        return 1
    print("ok         within the budget")
    return 0


if __name__ == "__main__":
    sys.exit(main())
