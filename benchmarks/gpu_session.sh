#!/usr/bin/env bash
# Issue 21's GPU checks in one call, for a session that is lent a GPU machine by the device tool.
#
# Prepared so that the checks fit the session's 15 minutes of device time after the smoke call
# (benchmarks/gpu_smoke.sh, ~75 s): the GPU tests, the speed-against-error benchmark on the GPU and on its host CPU (the
# baseline on the same machine), and the paper's Fig. 6 study file on the GPU. Every result lands
# in $OUT (8 files: text, and the study's summary.json, study.png and runs.parquet).
#
# The device image has numpy, scipy, CuPy (cupy-cuda13x), pyarrow, matplotlib, tqdm, threadpoolctl
# and pytest, not array-api-compat: carry it as a wheel. Here, once, in the repository root:
#
#   echo /.whl/ >> .git/info/exclude
#   python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
#       -d .whl array-api-compat==1.16.0 array-api-strict==2.6.1
#
# then call the device tool's run with carry [".whl"], timeout_s 600 and the command
#
#   bash benchmarks/gpu_session.sh
#
# and record what comes back in docs/benchmarks.md ("Devices and batches"), docs/studies.md (Fig. 6
# regenerated on a GPU) and the issue's note, with the device the reply names.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/risloc-gpu-out}
mkdir -p "$OUT"
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
  && export PYTHONPATH="/tmp/site:$PWD" || { echo "gpu_session.sh: carry .whl (see the header)"; exit 2; }
export PYTHONUNBUFFERED=1
# one budget for the whole call (BUDGET seconds, default 570): each stage runs under its own cap and never past it
BUDGET=${BUDGET:-570}
t0=$(date +%s)
deadline() {  # deadline CAP command...: the command under min(CAP, what is left of the budget)
  local left=$(( BUDGET - ($(date +%s) - t0) - 5 ))
  local cap=$(( $1 < left ? $1 : left ))
  if (( cap < 10 )); then echo "skipped (budget spent): ${*:2}"; return 124; fi
  timeout "$cap" "${@:2}"
}
stamp() { echo "== $1 at $(( $(date +%s) - t0 )) s" | tee -a "$OUT/stages.txt"; }

stamp device
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee -a "$OUT/stages.txt"
python3 -c "import dsp; print(dsp.backend_for('cuda').summary()); print(dsp.backend_for('cpu').summary())" | tee -a "$OUT/stages.txt"

# 1. the GPU tests (CuPy against NumPy; the GPU noise law; rows independent of B; CPU vs GPU statistics)
stamp "GPU tests"
deadline 200 python3 -m pytest -q -m gpu tests/gpu -p no:cacheprovider --durations=6 -rA 2>&1 \
  | tee "$OUT/gpu_tests.txt" | tail -30

# 2. speed beside error: the GPU at several batch sizes, then this machine's CPU (one core) as the baseline
stamp "bench, GPU"
deadline 60 python3 benchmarks/bench_device.py --device cuda --estimators refined --runs 32 --tx-powers 0,20 \
  --batches 1,8,64 2>&1 | tee "$OUT/bench_cuda.txt"
deadline 30 python3 benchmarks/bench_device.py --device cuda --estimators paper --runs 16 --tx-powers 10 \
  --batches 1,16 2>&1 | tail -n +3 | tee -a "$OUT/bench_cuda.txt"
stamp "bench, host CPU"
deadline 40 python3 benchmarks/bench_device.py --device cpu --runs 6 --tx-powers 10 --batches 1 2>&1 \
  | tee "$OUT/bench_cpu.txt"

# 3. the paper's Fig. 6 with its study file's 1000 runs per point, on the GPU (14 host workers share it: the
#    estimators' steps after the detection run on the host)
stamp "Fig. 6 on the GPU"
start=$(date +%s)
deadline 300 python3 -m risloc_rt study sweep --study studies/fig6_tx_power.toml --device cuda --workers 14 \
  --out /tmp/fig6 --quiet 2>&1 | tee "$OUT/fig6.txt"
echo "fig6 wall: $(( $(date +%s) - start )) s" | tee -a "$OUT/fig6.txt"
for f in summary.json study.png runs.parquet; do cp "/tmp/fig6/$f" "$OUT/fig6_$f"; done  # 8 files come back at most
stamp done
