#!/usr/bin/env bash
# The checks to run when a GPU is lent (docs/bench.md, "On a GPU"), in the order of what they
# are worth per minute, each under its own time limit, every result also written to $OUT:
#   OUT=/tmp/cuda bash benchmarks/cuda_check.sh
# 1. the position update's launch, part by part (1 ms until 2026-11-27); 2. the per-task profile;
# 3. ms/step by stage for the pyramid, the pile and the 5000-box scene; 4. the solver and stacking
# tests on CUDA (stops at the fourth failure, tracebacks kept). Needs taichi importable
# (pip install -e ., or the device README's wheels on PYTHONPATH).
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-out/cuda}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 PYTHONPATH="${PYTHONPATH:+$PYTHONPATH:}$PWD"
PY=${PY:-python3}
nvidia-smi -L 2>&1 | tee "$OUT/device.txt"
timeout -k 10 120 "$PY" benchmarks/position_update_probe.py --arch cuda 2>&1 | tee "$OUT/probe.txt"
timeout -k 10 60 "$PY" benchmarks/kernel_times.py --arch cuda --scene pile_1000 --settle 60 --steps 20 --tasks \
    > "$OUT/tasks.txt" 2>&1
head -40 "$OUT/tasks.txt"
timeout -k 10 120 "$PY" benchmarks/step_bench.py --arch cuda --scenes pyramid_20,pile_1000,headline_pile_5000 \
    --solvers mass-splitting,jacobi --iterations 15 --settle 60 --steps 30 2>&1 | tee "$OUT/step_bench.txt"
SANDBOX_TEST_ARCH=cuda timeout -k 20 180 "$PY" -m pytest -q --tb=short -n 8 --maxfail=4 -p no:cacheprovider -p no:benchmark \
    tests/test_hard_cases.py tests/test_solvers.py tests/test_stacking.py tests/solvers tests/test_guard.py \
    > "$OUT/pytest.txt" 2>&1
status=$?
tail -40 "$OUT/pytest.txt"
exit $status
