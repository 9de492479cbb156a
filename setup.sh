#!/usr/bin/env bash
# One-step set-up of risloc-rt on a fresh Debian machine (Python >= 3.11, run as root or with sudo):
# Debian's python3-venv and libllvm19 when missing (and chromium for --test), then a virtual environment with pinned packages.
#
#   ./setup.sh           create .venv and install risloc-rt (then: .venv/bin/risloc demo)
#   ./setup.sh --test    the same plus the test tools     (then: .venv/bin/python -m pytest)
#
# Idempotent: a second run only checks what is already there. PYTHON=/path/to/python3 picks
# the interpreter; VENV=dir the environment (default .venv beside this file).
set -euo pipefail
cd "$(dirname "$0")"

extras=""
for arg in "$@"; do
  case "$arg" in
    --test) extras="[test]" ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown option $arg (use --test or --help)" >&2; exit 2 ;;
  esac
done

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
if [ "$extras" = "[test]" ] && ! command -v chromium >/dev/null; then need_apt+=(chromium); fi
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
"$VENV/bin/python" -m pip install -q --disable-pip-version-check \
  -c requirements/constraints.txt -e ".$extras"
echo "setup.sh: ready — $("$VENV/bin/risloc" --help | head -n 1)"
