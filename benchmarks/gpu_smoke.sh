#!/usr/bin/env bash
# Issue 21's first GPU call: a short smoke test of the CuPy path (about 2 minutes of device time) before
# the long call (benchmarks/gpu_session.sh), so that a fault found here can be fixed on the CPU machine
# and the long call still fits the session's device time. Carry .whl as gpu_session.sh's header says;
# call the device tool's run with carry [".whl"], timeout_s 300 and the command
#
#   bash benchmarks/gpu_smoke.sh
#
# Stages (each with its own limit; a failure is printed with its traceback and the next stage runs):
# the device line, the fast GPU tests (CuPy against NumPy, the GPU noise law, rows independent of B),
# a few Table I runs per batch size on the GPU, and a 2-point study through the CLI on the GPU.
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/risloc-gpu-out}
mkdir -p "$OUT"
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
  && export PYTHONPATH="/tmp/site:$PWD" || { echo "gpu_smoke.sh: carry .whl (see gpu_session.sh's header)"; exit 2; }
export PYTHONUNBUFFERED=1
start=$(date +%s)
stamp() { echo "== $1 at $(( $(date +%s) - start )) s" | tee -a "$OUT/smoke.txt"; }

stamp device
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>&1 | tee -a "$OUT/smoke.txt"
python3 -c "import cupy, numpy, scipy; print('cupy', cupy.__version__, 'numpy', numpy.__version__, 'scipy', scipy.__version__)" 2>&1 | tee -a "$OUT/smoke.txt"
timeout 60 python3 -c "import dsp; print(dsp.backend_for('cuda').summary())" 2>&1 | tee -a "$OUT/smoke.txt"

stamp "fast GPU tests"
timeout 120 python3 -m pytest -q -m "gpu and not slow" tests/gpu -p no:cacheprovider -x --tb=long 2>&1 | tee "$OUT/smoke_tests.txt" | tail -40

stamp "bench on the GPU"
timeout 60 python3 benchmarks/bench_device.py --device cuda --runs 16 --tx-powers 10 --batches 1,16 2>&1 | tee -a "$OUT/smoke.txt"

stamp "study on the GPU"
timeout 60 python3 -m risloc_rt study sweep --study studies/fig6_tx_power.toml --device cuda --workers 4 --runs 8 \
  --out "$OUT/smoke_study" 2>&1 | tail -25 | tee -a "$OUT/smoke.txt"
stamp done
