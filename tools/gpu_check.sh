#!/usr/bin/env bash
# The GPU check (issue 28; offline install and the folder it reports into, issue 44): one
# command on a GPU machine with this repository (and ../shared beside it, or shared/ inside
# it, when present). It sets the environment up: from an offline wheelhouse
# (tools/offline_wheels.sh: the repacked mitsuba, drjit, pytest and tqdm, installed with
# pip --no-index --target into a scratch folder on top of the interpreter's numpy and scipy),
# or with the Makefile's own target (make setup), or it takes an interpreter as it is. Then it
# runs the gpu tests (tests/test_gpu.py: CUDA against LLVM within standard errors, among
# others), benchmarks/throughput.py against stock `path` on the variant checked, the same
# benchmark's two moving bodies with dopplertof on llvm_ad_rgb (the ratio of the times per
# sample), and writes a short report (tools/gpu_report.py: GPU, driver, CUDA, libLLVM,
# pass/fail counts, CUDA-against-LLVM agreement, throughput ratios) to OUT/report.txt and
# stdout, the steps' logs beside it. Every step has a time limit and the whole check stays
# under 8 minutes; exit 0 only when everything passed.
#
#   tools/gpu_check.sh --out DIR [--wheelhouse WH] [--python PY] [--variant cuda_ad_rgb]
#                      [--quick]
#
# --out DIR        the folder the report and logs go to (created; not the repository root):
#                  report.txt, steps.txt, junit.xml, tests.log, throughput.txt,
#                  throughput_llvm.txt, throughput_fallback.txt (when the fused kernels
#                  failed), install.log or setup.log
# --wheelhouse WH  install from the wheels in WH (no package index is asked) into a new
#                  scratch folder (GPU_CHECK_SITE, kept; default a new one under /tmp,
#                  removed at the end), with PY or
#                  python3, and run the steps with that folder and src/ on PYTHONPATH
# --python PY      without --wheelhouse: use this interpreter as it is instead of
#                  `make setup` (the dry run; a machine where mitsuba and drjit are installed)
# --quick          a few tests and a tiny benchmark, seconds (tests/test_gpu_check.py runs it
#                  on llvm_ad_rgb in the normal suite, so that the script cannot rot)
# GPU_CHECK_BUDGET_S (environment): the steps' time limit together, 440 s by default (with
#              the kills' 10 s grace, the checks before and the report: under 8 minutes)
# Exit status: 0 passed, 1 a step or a test failed (the report says which) or the set-up
#              failed (one line), 2 bad arguments.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VARIANT=cuda_ad_rgb OUT="" PY="" WHEELHOUSE="" QUICK=0
BUDGET_S="${GPU_CHECK_BUDGET_S:-440}"  # the steps together (s)
# ---- Arguments ----
while [ $# -gt 0 ]; do
  case "$1" in
    --variant|--out|--python|--wheelhouse)
      [ $# -ge 2 ] || { echo "gpu_check.sh: $1 needs a value" >&2; exit 2; }
      case "$1" in --variant) VARIANT="$2";; --out) OUT="$2";;
                   --python) PY="$2";; --wheelhouse) WHEELHOUSE="$2";; esac
      shift 2;;
    --quick) QUICK=1; shift;;
    *) echo "gpu_check.sh: unknown argument '$1' (see the header of tools/gpu_check.sh)" >&2
       exit 2;;
  esac
done
case "$BUDGET_S" in ''|*[!0-9]*)
  echo "gpu_check.sh: GPU_CHECK_BUDGET_S=$BUDGET_S: expected a whole number of seconds" >&2
  exit 2;; esac
case "$VARIANT" in llvm_*|cuda_*) ;; *)
  echo "gpu_check.sh: --variant $VARIANT: expected a cuda_* or llvm_* variant" >&2; exit 2;; esac
[ -n "$OUT" ] || { echo "gpu_check.sh: --out DIR is needed (the folder the report goes to)" >&2
                   exit 2; }
OUT_PARENT="$(dirname -- "$OUT")"
[ -d "$OUT_PARENT" ] && [ -w "$OUT_PARENT" ] || {
  echo "gpu_check.sh: --out $OUT: folder $OUT_PARENT does not exist or is not writable" >&2
  exit 2; }
[ ! -e "$OUT" ] || [ -d "$OUT" ] || { echo "gpu_check.sh: --out $OUT is a file" >&2; exit 2; }
OUT_ABS="$(cd "$OUT_PARENT" && pwd)/$(basename -- "$OUT")"  # the steps run in $ROOT
if [ -d "$OUT" ] && [ "$(cd "$OUT" && pwd -P)" = "$(cd "$ROOT" && pwd -P)" ]; then
  echo "gpu_check.sh: --out $OUT is the repository root: give the report a folder of its own" >&2
  exit 2
fi
if [ -n "$PY" ] && ! command -v "$PY" >/dev/null 2>&1; then
  echo "gpu_check.sh: --python $PY: no such interpreter" >&2; exit 2
fi
case "$PY" in */*) PY="$(cd "$(dirname -- "$PY")" && pwd)/$(basename -- "$PY")";; esac
if [ -n "$WHEELHOUSE" ]; then
  [ -d "$WHEELHOUSE" ] || { echo "gpu_check.sh: --wheelhouse $WHEELHOUSE: no such folder" >&2
                            exit 2; }
  WHEELHOUSE="$(cd "$WHEELHOUSE" && pwd)"
  compgen -G "$WHEELHOUSE/mitsuba-*.whl" >/dev/null || {
    echo "gpu_check.sh: --wheelhouse $WHEELHOUSE: no mitsuba wheel in it (make it with tools/offline_wheels.sh)" >&2
    exit 2; }
  [ -n "$PY" ] || PY="$(command -v python3)" || { echo "gpu_check.sh: no python3 for --wheelhouse" >&2; exit 2; }
fi
mkdir -p "$OUT" || exit 2
OUT="$OUT_ABS"
REPORT="$OUT/report.txt"
# an earlier run's files in the folder must not be read as this one's
rm -f "$OUT"/{report.txt,steps.txt,junit.xml,throughput.txt,throughput_fallback.txt} \
      "$OUT"/{throughput_llvm.txt,setup.log,install.log,tests.log}
: > "$OUT/steps.txt"
START=$SECONDS

# ---- A step: its own time limit, cut to what is left of the budget ----
step() {  # step NAME LIMIT_S LOGFILE COMMAND...
  local name="$1" limit="$2" log="$3"; shift 3
  local left=$(( BUDGET_S - (SECONDS - START) )) began=$SECONDS status=ok rc
  [ "$left" -lt "$limit" ] && limit=$left
  if [ "$limit" -le 0 ]; then echo "$name no-time-left 0" >> "$OUT/steps.txt"; return 1; fi
  echo "== $name (limit ${limit} s; log $log)"
  (cd "$ROOT" && timeout --kill-after=10 "$limit" "$@") > "$log" 2>&1
  rc=$?
  if [ $rc -eq 124 ] || [ $rc -eq 137 ]; then status="timed-out-after-${limit}s"
  elif [ $rc -ne 0 ]; then status="exit-$rc"; fi
  echo "$name $status $(( SECONDS - began ))" >> "$OUT/steps.txt"
  [ "$status" = ok ] || tail -n 15 "$log"
  [ "$status" = ok ]
}

# ---- Set-up: the wheelhouse, the Makefile's own, or the interpreter given ----
if [ -n "$WHEELHOUSE" ]; then
  missing="$("$PY" -c 'import importlib.util as u
print(" ".join(m for m in ("numpy", "scipy") if u.find_spec(m) is None))' 2>&1)" || missing="numpy scipy"
  [ -z "$missing" ] || {
    echo "gpu_check.sh: $PY lacks $missing, which the wheelhouse does not carry (a scientific Python image has them)" >&2
    exit 1; }
  if [ -z "${GPU_CHECK_SITE:-}" ]; then  # a scratch folder of its own, removed at the end
    SITE="$(mktemp -d /tmp/gpu_check_site.XXXXXX)" || {
      echo "gpu_check.sh: cannot create a scratch folder under /tmp" >&2; exit 1; }
    trap 'rm -rf "$SITE"' EXIT
  else SITE="$GPU_CHECK_SITE"; fi
  mkdir -p "$SITE" || { echo "gpu_check.sh: cannot create the install folder $SITE" >&2; exit 1; }
  SITE="$(cd "$SITE" && pwd -P)"
  # what the interpreter lacks of the tests' needs comes from the wheelhouse too
  NEEDS=(mitsuba)
  "$PY" -c 'import pytest, sys; sys.exit(tuple(map(int, pytest.__version__.split(".")[:2])) < (7, 4))' \
    2>/dev/null || NEEDS+=("pytest>=7.4,<10")
  "$PY" -c 'import tqdm' 2>/dev/null || NEEDS+=("tqdm>=4.60,<5")
  step install 90 "$OUT/install.log" "$PY" -m pip install --no-index --find-links "$WHEELHOUSE" \
      --disable-pip-version-check --no-compile --target "$SITE" --upgrade "${NEEDS[@]}" || {
    echo "gpu_check.sh: pip install from $WHEELHOUSE failed: $(grep -E 'ERROR' "$OUT/install.log" | tail -n 1) (log: $OUT/install.log)" >&2
    exit 1; }
  export PYTHONPATH="$SITE:$ROOT/src${PYTHONPATH:+:$PYTHONPATH}"
  where="$("$PY" -c 'import mitsuba, os; print(os.path.dirname(os.path.realpath(mitsuba.__file__)))' 2>&1)"
  [ "$where" = "$SITE/mitsuba" ] || {
    echo "gpu_check.sh: mitsuba is not imported from $SITE after the install: $(echo "$where" | tail -n 1)" >&2
    exit 1; }
elif [ -z "$PY" ]; then
  step setup 240 "$OUT/setup.log" make setup || {
    echo "gpu_check.sh: make setup failed: no report (log: $OUT/setup.log)" >&2; exit 1; }
  PY="$ROOT/.venv/bin/python"
fi

# ---- The gpu tests, the throughput against stock path, then against dopplertof on LLVM ----
TEST_ARGS=(-m gpu tests/test_gpu.py -q -rs -p no:cacheprovider -o junit_family=xunit1
           --junitxml "$OUT/junit.xml")
BENCH_ARGS=(--repeats 3)
if [ "$QUICK" = 1 ]; then
  TEST_ARGS+=(-k "same_seed or (agrees and moving_plane)")
  BENCH_ARGS=(--quick --res 8 --spp 4 --repeats 1)
fi
step tests 180 "$OUT/tests.log" "$PY" -m pytest "${TEST_ARGS[@]}"
step throughput 150 "$OUT/throughput.txt" \
    "$PY" benchmarks/throughput.py --variant "$VARIANT" "${BENCH_ARGS[@]}" ||
  # the fused kernels failed (OptiX: several pipelines in one kernel?): the fallback's numbers
  step throughput-one-scene-per-kernel 120 "$OUT/throughput_fallback.txt" \
    "$PY" benchmarks/throughput.py --variant "$VARIANT" "${BENCH_ARGS[@]}" --one-scene-per-kernel
case "$VARIANT" in
  llvm_*) ;;  # the variant is LLVM's own: no ratio to take
  *) # the two moving bodies at the same size as above (--quick) on LLVM: time per sample
     step throughput-llvm 60 "$OUT/throughput_llvm.txt" \
       "$PY" benchmarks/throughput.py --variant llvm_ad_rgb --quick "${BENCH_ARGS[@]}";;
esac

# ---- The report (stdout and the file); its exit status is the check's ----
echo "== report ($REPORT)"
(cd "$ROOT" && "$PY" tools/gpu_report.py --variant "$VARIANT" --logs "$OUT" --report "$REPORT")
