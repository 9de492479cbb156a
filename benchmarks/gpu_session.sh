#!/usr/bin/env bash
# Issue 21's GPU checks in one call, for a session that is lent a GPU machine by the device tool.
#
# Prepared so that the checks fit the session's 15 minutes of device time in one run (about 8-10
# minutes): the GPU tests, the speed-against-error benchmark on the GPU and on its host CPU (the
# baseline on the same machine), and the paper's Fig. 6 study file on the GPU. Every result lands
# in $OUT (text files; the study's summary.json and study.png).
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
deadline() { timeout "$1" "${@:2}"; }  # each stage has its own limit: a hang costs that stage only

nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee "$OUT/device.txt"
python3 -c "import dsp; print(dsp.backend_for('cuda').summary())" | tee -a "$OUT/device.txt"

# 1. the GPU tests (CuPy against NumPy; the GPU noise law; rows independent of B; CPU vs GPU statistics)
deadline 240 python3 -m pytest -q -m gpu tests/gpu -p no:cacheprovider --durations=5 2>&1 \
  | tee "$OUT/gpu_tests.txt"

# 2. speed beside error: the GPU at several batch sizes, then this machine's CPU (one core) as the baseline
deadline 150 python3 benchmarks/bench_device.py --device cuda --runs 64 --tx-powers 0,10,20 --batches 1,8,32,64 2>&1 \
  | tee "$OUT/bench_cuda.txt"
deadline 60 python3 benchmarks/bench_device.py --device cpu --runs 6 --tx-powers 10 --batches 1 2>&1 \
  | tee "$OUT/bench_cpu.txt"

# 3. the paper's Fig. 6 with its study file's 1000 runs per point, on the GPU (14 host workers share it: the
#    estimators' steps after the detection run on the host)
start=$(date +%s)
deadline 200 python3 -m risloc_rt study sweep --study studies/fig6_tx_power.toml --device cuda --workers 14 \
  --out "$OUT/fig6" --quiet 2>&1 | tee "$OUT/fig6.txt"
echo "fig6 wall: $(( $(date +%s) - start )) s" | tee -a "$OUT/fig6.txt"
ls "$OUT"
