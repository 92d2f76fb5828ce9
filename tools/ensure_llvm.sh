#!/usr/bin/env bash
# Make sure a libLLVM that Dr.Jit 1.5 can use (>= 16) is present; install Debian's
# libllvm19 when running as root, otherwise say what to install.
set -euo pipefail
PY="${1:-python3}"
if "$PY" -c 'import sys; from dopplertof.backend import find_libllvm, ensure_libllvm; ensure_libllvm(); sys.exit(0)' 2>/dev/null; then
  exit 0
fi
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing libllvm19 (Dr.Jit's LLVM backend needs LLVM >= 16)..."
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y -qq libllvm19 >/dev/null 2>&1 || { apt-get update -qq >/dev/null && apt-get install -y -qq libllvm19 >/dev/null; }
  "$PY" -c 'from dopplertof.backend import ensure_libllvm; print("libLLVM:", ensure_libllvm())'
  exit 0
fi
echo "error: no usable libLLVM (>= 16) for Mitsuba's LLVM variants." >&2
echo "       install it, e.g. 'sudo apt-get install libllvm19', or set DRJIT_LIBLLVM_PATH." >&2
exit 1
