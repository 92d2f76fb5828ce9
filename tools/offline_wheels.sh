#!/usr/bin/env bash
# The offline wheelhouse for a GPU node (issue 44, 2026-12-03): GPU nodes often reach no
# package index, and a transfer can be limited to 64 MiB, so what tools/gpu_check.sh needs
# beyond a scientific Python image travels as wheels, under 50 MB together:
#
#   tools/offline_wheels.sh OUT [--python-version 3.12]
#
# - mitsuba 3.9.x (repacked by tools/repack_wheel.py to cuda_ad_rgb and llvm_ad_rgb: the
#   other eleven variants' modules, the spectral table and the C++ headers left out,
#   62.6 MB -> about 40 MB) and drjit 1.5.x, the one that mitsuba pins;
# - what the gpu tests (tests/test_gpu.py), benchmarks/throughput.py and tools/gpu_report.py
#   import beyond the standard library, numpy and scipy (measured 2026-12-03 by running them
#   with the imported modules listed): pytest with what it needs (pluggy, iniconfig,
#   packaging, pygments) and tqdm. numpy and scipy are the image's (tools/gpu_check.sh says
#   so in one line where they are missing); matplotlib, h5py and dask are not imported by
#   the check.
#
# Wheels for CPython on x86-64 Linux (manylinux_2_28 and older), binary only; OUT must be a
# new or empty folder. Prints each wheel's size and the total; exit 1 with one line on
# stderr when a download fails (no package index reachable, say), the repack fails, or the
# total is over 50 MB; 2 for bad arguments. PYTHON (environment): the pip to download with
# (default python3).
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3}"
PYVER=3.12
LIMIT_BYTES=50000000   # 50 MB
OUT=""
while [ $# -gt 0 ]; do
  case "$1" in
    --python-version)
      [ $# -ge 2 ] || { echo "offline_wheels.sh: --python-version needs a value" >&2; exit 2; }
      PYVER="$2"; shift 2;;
    -*) echo "offline_wheels.sh: unknown argument '$1' (usage: tools/offline_wheels.sh OUT [--python-version 3.12])" >&2
        exit 2;;
    *) [ -z "$OUT" ] || { echo "offline_wheels.sh: one OUT folder only ('$OUT', then '$1')" >&2; exit 2; }
       OUT="$1"; shift;;
  esac
done
[ -n "$OUT" ] || { echo "offline_wheels.sh: no OUT folder (usage: tools/offline_wheels.sh OUT [--python-version 3.12])" >&2; exit 2; }
case "$PYVER" in 3.[0-9]|3.[0-9][0-9]) ;; *)
  echo "offline_wheels.sh: --python-version $PYVER: expected 3.N" >&2; exit 2;; esac
command -v "$PY" >/dev/null 2>&1 || { echo "offline_wheels.sh: PYTHON=$PY: no such interpreter" >&2; exit 2; }
if [ -e "$OUT" ] && { [ ! -d "$OUT" ] || [ -n "$(ls -A "$OUT")" ]; }; then
  echo "offline_wheels.sh: $OUT exists and is not an empty folder (an earlier wheelhouse must not mix with this one)" >&2
  exit 2
fi
mkdir -p "$OUT" || { echo "offline_wheels.sh: cannot create $OUT" >&2; exit 2; }

STAGE="$(mktemp -d "${TMPDIR:-/tmp}/offline_wheels.XXXXXX")" || exit 1
trap 'rm -rf "$STAGE"' EXIT
PLATFORMS=()
for p in manylinux_2_28_x86_64 manylinux_2_27_x86_64 manylinux_2_17_x86_64 manylinux2014_x86_64; do
  PLATFORMS+=(--platform "$p")
done

# ---- Download: the requirements with their dependencies for that Python (binary only) ----
echo "== downloading for CPython $PYVER, x86-64 Linux (log: kept only on failure)"
if ! "$PY" -m pip download --disable-pip-version-check --only-binary=:all: \
      --python-version "$PYVER" --implementation cp \
      "${PLATFORMS[@]}" -d "$STAGE/dl" \
      "mitsuba>=3.9.0,<3.10" "drjit>=1.5.0,<1.6" "pytest>=7.4,<10" "tqdm>=4.60,<5" \
      > "$STAGE/pip.log" 2>&1; then
  cp "$STAGE/pip.log" "$OUT/pip_download.log" 2>/dev/null
  why="$(grep -E '^ERROR|Error|error:' "$STAGE/pip.log" | grep -v '^WARNING' | tail -n 1)"
  echo "offline_wheels.sh: pip download failed (package index unreachable or no matching wheel): ${why:-see $OUT/pip_download.log}" >&2
  exit 1
fi
MITSUBA=("$STAGE"/dl/mitsuba-*.whl)
[ -f "${MITSUBA[0]}" ] || { echo "offline_wheels.sh: pip download saved no mitsuba wheel" >&2; exit 1; }

# ---- Repack Mitsuba; the others as they came ----
"$PY" "$ROOT/tools/repack_wheel.py" "${MITSUBA[0]}" "$OUT" --variants cuda_ad_rgb,llvm_ad_rgb \
  > /dev/null || exit 1
for w in "$STAGE"/dl/*.whl; do
  [ "$w" = "${MITSUBA[0]}" ] || mv "$w" "$OUT/" || { echo "offline_wheels.sh: cannot move $w to $OUT" >&2; exit 1; }
done

# ---- Sizes ----
"$PY" - "$OUT" "$LIMIT_BYTES" "$(basename "${MITSUBA[0]}")" "$(stat -c %s "${MITSUBA[0]}")" <<'EOF'
import os, sys
out, limit, original, original_size = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
wheels = sorted(f for f in os.listdir(out) if f.endswith(".whl"))
total = 0
for name in wheels:
    size = os.path.getsize(os.path.join(out, name))
    total += size
    print(f"{size / 1e6:8.2f} MB  {name}")
print(f"{original_size / 1e6:8.2f} MB  ({original} before the repack)")
print(f"{total / 1e6:8.2f} MB  total, {len(wheels)} wheels in {out} (limit {limit / 1e6:.0f} MB)")
if total > limit:
    print(f"offline_wheels.sh: the wheelhouse is {total / 1e6:.2f} MB, over {limit / 1e6:.0f} MB",
          file=sys.stderr)
    sys.exit(1)
EOF
