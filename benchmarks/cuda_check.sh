#!/usr/bin/env bash
# The checks to run when a GPU is lent (docs/bench.md, "On a GPU"), in the order of what they
# are worth per minute, each under its own time limit, every result also written to $OUT:
#   OUT=/tmp/cuda bash benchmarks/cuda_check.sh
# 1. ms/step by stage for the pyramid, the pile and the 5000-box scene (the fourth run, docs/bench.md
# "The fourth CUDA run", H200: mass splitting 3.0-4.3 / 3.1-4.4 / 5.4 ms/step; Jacobi's step
# outside the loop ~1 ms more than mass splitting's, not yet explained), and first the same for
# another tree when BASELINE names one (a carried copy of an older commit: the two timed on the
# same card); 2. the per-task profile of a pile step (13 substep tasks, none serial; 8 in a world
# without light bodies' sweeps), and Jacobi's on the pyramid; 3. the engine tests most likely to meet a GPU-only problem on CUDA
# (stops at the fourth failure, tracebacks kept).
# About 7 minutes on an H200, 9 with a BASELINE. Needs taichi importable (pip install -e ., or the device README's
# wheels on PYTHONPATH).
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-out/cuda}
mkdir -p "$OUT"
SITE=${PYTHONPATH:-}
export PYTHONUNBUFFERED=1 PYTHONPATH="${SITE:+$SITE:}$PWD"
PY=${PY:-python3}
BENCH=(benchmarks/step_bench.py --arch cuda --scenes pyramid_20,pile_1000,headline_pile_5000 --solvers mass-splitting,jacobi
       --iterations 15 --settle 60 --steps 30)
nvidia-smi -L 2>&1 | tee "$OUT/device.txt"
if [ -n "${BASELINE:-}" ]; then
    (cd "$BASELINE" && PYTHONPATH="${SITE:+$SITE:}$PWD" timeout -k 10 120 "$PY" "${BENCH[@]}") 2>&1 \
        | tee "$OUT/step_bench_baseline.txt"
fi
timeout -k 10 120 "$PY" "${BENCH[@]}" 2>&1 | tee "$OUT/step_bench.txt"
timeout -k 10 60 "$PY" benchmarks/kernel_times.py --arch cuda --scene pile_1000 --settle 60 --steps 20 --tasks \
    > "$OUT/tasks.txt" 2>&1
head -40 "$OUT/tasks.txt"
# Jacobi's prepare on the card (~1 ms more than mass splitting's in the fourth run): its tasks
timeout -k 10 60 "$PY" benchmarks/kernel_times.py --arch cuda --scene pyramid_20 --solver jacobi --settle 60 --steps 20 \
    --tasks > "$OUT/tasks_jacobi.txt" 2>&1
grep -E "prepare_step|^  " "$OUT/tasks_jacobi.txt" | head -30
SANDBOX_TEST_ARCH=cuda timeout -k 20 300 "$PY" -m pytest -q --tb=short -n 14 --maxfail=4 -p no:cacheprovider \
    -p no:benchmark tests/test_guard.py tests/test_hard_cases.py tests/test_solvers.py tests/test_stacking.py \
    tests/solvers tests/test_sleeping.py tests/test_dispatch.py > "$OUT/pytest.txt" 2>&1
status=$?
tail -40 "$OUT/pytest.txt"
exit $status
