#!/usr/bin/env bash
# One-step set-up of risloc-rt on a fresh Debian machine (Python >= 3.11, run as root or with sudo):
# Debian's python3-venv and libllvm19 when missing (and chromium for --test), then a virtual environment with pinned packages.
#
#   ./setup.sh           create .venv and install risloc-rt (then: .venv/bin/risloc demo)
#   ./setup.sh --test    the same plus the test tools     (then: .venv/bin/python -m pytest)
#   ./setup.sh --gpu     the same plus CuPy for an NVIDIA GPU (then: risloc ... --device cuda); it also
#                        installs CUDA 12's libraries from pip when the machine has no CUDA toolkit, needs
#                        the NVIDIA driver (CUDA 12: driver 525 or newer) and says whether the GPU works
#   ./setup.sh --test --gpu   both (then: .venv/bin/python -m pytest -m gpu runs the GPU tests)
#
# Idempotent: a second run only checks what is already there. PYTHON=/path/to/python3 picks
# the interpreter; VENV=dir the environment (default .venv beside this file).
set -euo pipefail
cd "$(dirname "$0")"

test=""; gpu=""
for arg in "$@"; do
  case "$arg" in
    --test) test=1 ;;
    --gpu) gpu=1 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown option $arg (use --test, --gpu or --help)" >&2; exit 2 ;;
  esac
done
extras=""
[ -n "$test" ] && extras="test"
[ -n "$gpu" ] && extras="${extras:+$extras,}gpu"
[ -n "$extras" ] && extras="[$extras]"

PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}

need_apt=()
"$PYTHON" -c 'import venv, ensurepip' 2>/dev/null || need_apt+=(python3-venv)
# sionna-rt's CPU backend (Dr.Jit LLVM) needs libLLVM >= 17: drjit 1.5 aborts with LLVM 15/16
# and refuses 14. Debian 12 ships libllvm19.
have_llvm=""
for lib in /usr/lib/*-linux-gnu/libLLVM.so.{17,18,19,20,21}* /usr/lib/*-linux-gnu/libLLVM-{17,18,19,20,21}.so*; do
  [ -e "$lib" ] && have_llvm="$lib" && break
done
[ -n "$have_llvm" ] || [ -n "${DRJIT_LIBLLVM_PATH:-}" ] || need_apt+=(libllvm19)
# --test only: Debian's chromium, the headless browser tests/measured/test_compare.py opens the
# 'risloc compare' page in (no browser download; the test is skipped without it).
if [ -n "$test" ] && ! command -v chromium >/dev/null; then need_apt+=(chromium); fi
if ((${#need_apt[@]})); then
  if command -v apt-get >/dev/null; then
    SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
    echo "setup.sh: installing Debian packages: ${need_apt[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}"
  else
    echo "setup.sh: missing ${need_apt[*]} and no apt-get to install them; install them and re-run" >&2
    exit 1
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup.sh: creating $VENV with $("$PYTHON" --version)"
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
# --gpu: CuPy's wheel loads cuFFT, cuRAND and NVRTC from a CUDA 12 toolkit; on a machine without one
# (only the driver), CuPy's "ctk" extra brings them from pip (pinned in the constraints).
gpu_libs=()
if [ -n "$gpu" ]; then
  if ! command -v nvidia-smi >/dev/null && [ ! -e /proc/driver/nvidia/version ]; then
    echo "setup.sh: no NVIDIA driver on this machine (no nvidia-smi, no /proc/driver/nvidia): CuPy is installed but --device cuda will refuse until you install the driver for your GPU (Debian: nvidia-driver from non-free, 525 or newer) and reboot; meanwhile use --device cpu" >&2
  fi
  have_toolkit=""
  for lib in $(ldconfig -p 2>/dev/null | awk '/libnvrtc\.so\.12/ {print $NF}') /usr/local/cuda*/lib64/libnvrtc.so.12* \
             ${CUDA_PATH:+"$CUDA_PATH"/lib64/libnvrtc.so.12*}; do
    [ -e "$lib" ] && have_toolkit="$lib" && break
  done
  [ -n "$have_toolkit" ] || gpu_libs=("cupy-cuda12x[ctk]")
fi
"$VENV/bin/python" -m pip install -q --disable-pip-version-check \
  -c requirements/constraints.txt -e ".$extras" ${gpu_libs[@]+"${gpu_libs[@]}"}
if [ -n "$gpu" ]; then  # report, never fail: the CPU path works without a GPU
  "$VENV/bin/python" - <<'PY' || true
import dsp
ok, why = dsp.cuda_available()
if not ok:
    print(f"setup.sh: no usable GPU ({why}); the DSP runs on the CPU (--device cpu)")
else:
    try:  # load what the DSP uses on the GPU: cuFFT, cuRAND and NVRTC (an elementwise kernel)
        import numpy as np
        backend = dsp.backend_for("cuda")
        x = backend.device_normals(np.random.default_rng(0), (4, 8))
        backend.to_host(backend.ifft(x * 2, n=16, axis=1))
        print(f"setup.sh: GPU ready: {backend.summary()}")
    except Exception as exc:  # noqa: BLE001 - a report
        print(f"setup.sh: CuPy finds the GPU but fails to run on it ({type(exc).__name__}: "
              f"{str(exc).splitlines()[0] if str(exc) else ''}); use --device cpu until CUDA 12 works")
PY
fi
echo "setup.sh: ready — $("$VENV/bin/risloc" --help | head -n 1)"
