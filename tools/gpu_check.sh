#!/usr/bin/env bash
# The GPU check (issue 28): one command on a bare GPU machine with this repository (and
# ../shared beside it, or shared/ inside it, when present). It sets the environment up with the Makefile's own
# target (make setup: the venv and libLLVM), runs the gpu tests (tests/test_gpu.py),
# runs benchmarks/throughput.py against stock `path` on the GPU, and writes a short
# report (tools/gpu_report.py: GPU, driver, CUDA, pass/fail counts, CUDA-against-LLVM
# agreement, throughput ratio) to the report file and stdout. Every step has a time
# limit and the whole check stays under 8 minutes; exit 0 only when everything passed.
#
#   tools/gpu_check.sh [--variant cuda_ad_rgb] [--report gpu_report.txt] [--logs DIR]
#                      [--python PY] [--quick]
#
# --python PY  use this interpreter as it is instead of `make setup` (the dry run; or a
#              machine without network, where mitsuba and drjit were installed by hand)
# --quick      a few tests and a tiny benchmark, seconds (tests/test_gpu_check.py runs it
#              on llvm_ad_rgb in the normal suite, so that the script cannot rot)
# --logs DIR   where the steps' output goes (default: a new folder under /tmp)
# GPU_CHECK_BUDGET_S (environment): the steps' time limit together, 420 s by default (with
#              the kills' 10 s grace and the report's seconds: under 8 minutes)
# Exit status: 0 passed, 1 a step or a test failed (the report says which), 2 bad arguments.
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VARIANT=cuda_ad_rgb REPORT=gpu_report.txt LOGS="" PY="" QUICK=0
BUDGET_S="${GPU_CHECK_BUDGET_S:-420}"  # the steps together (s)
# ---- Arguments ----
while [ $# -gt 0 ]; do
  case "$1" in
    --variant|--report|--logs|--python)
      [ $# -ge 2 ] || { echo "gpu_check.sh: $1 needs a value" >&2; exit 2; }
      case "$1" in --variant) VARIANT="$2";; --report) REPORT="$2";;
                   --logs) LOGS="$2";; --python) PY="$2";; esac
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
REPORT_DIR="$(dirname -- "$REPORT")"
[ -d "$REPORT_DIR" ] && [ -w "$REPORT_DIR" ] || {
  echo "gpu_check.sh: --report $REPORT: folder $REPORT_DIR does not exist or is not writable" >&2
  exit 2; }
[ ! -d "$REPORT" ] || { echo "gpu_check.sh: --report $REPORT is a folder" >&2; exit 2; }
REPORT="$(cd "$REPORT_DIR" && pwd)/$(basename -- "$REPORT")"  # the steps run in $ROOT
if [ -n "$PY" ] && ! command -v "$PY" >/dev/null 2>&1; then
  echo "gpu_check.sh: --python $PY: no such interpreter" >&2; exit 2
fi
case "$PY" in */*) PY="$(cd "$(dirname -- "$PY")" && pwd)/$(basename -- "$PY")";; esac
if [ -z "$LOGS" ]; then LOGS="$(mktemp -d /tmp/gpu_check.XXXXXX)"
else mkdir -p "$LOGS" || exit 2; fi
LOGS="$(cd "$LOGS" && pwd)"
# an earlier run's files in the folder must not be read as this one's
rm -f "$LOGS"/{steps.txt,junit.xml,throughput.txt,throughput_fallback.txt,setup.log,tests.log}
: > "$LOGS/steps.txt"
START=$SECONDS

# ---- A step: its own time limit, cut to what is left of the budget ----
step() {  # step NAME LIMIT_S LOGFILE COMMAND...
  local name="$1" limit="$2" log="$3"; shift 3
  local left=$(( BUDGET_S - (SECONDS - START) )) began=$SECONDS status=ok rc
  [ "$left" -lt "$limit" ] && limit=$left
  if [ "$limit" -le 0 ]; then echo "$name no-time-left 0" >> "$LOGS/steps.txt"; return 1; fi
  echo "== $name (limit ${limit} s; log $log)"
  (cd "$ROOT" && timeout --kill-after=10 "$limit" "$@") > "$log" 2>&1
  rc=$?
  if [ $rc -eq 124 ] || [ $rc -eq 137 ]; then status="timed-out-after-${limit}s"
  elif [ $rc -ne 0 ]; then status="exit-$rc"; fi
  echo "$name $status $(( SECONDS - began ))" >> "$LOGS/steps.txt"
  [ "$status" = ok ] || tail -n 15 "$log"
  [ "$status" = ok ]
}

# ---- Set-up: the Makefile's own (or the interpreter given) ----
if [ -z "$PY" ]; then
  step setup 240 "$LOGS/setup.log" make setup || {
    echo "gpu_check.sh: make setup failed: no report (log: $LOGS/setup.log)" >&2; exit 1; }
  PY="$ROOT/.venv/bin/python"
fi

# ---- The gpu tests, then the throughput against stock path ----
TEST_ARGS=(-m gpu tests/test_gpu.py -q -rs -p no:cacheprovider -o junit_family=xunit1
           --junitxml "$LOGS/junit.xml")
BENCH_ARGS=(--variant "$VARIANT" --repeats 3)
if [ "$QUICK" = 1 ]; then
  TEST_ARGS+=(-k "same_seed or (agrees and moving_plane)")
  BENCH_ARGS=(--variant "$VARIANT" --quick --res 8 --spp 4 --repeats 1)
fi
step tests 180 "$LOGS/tests.log" "$PY" -m pytest "${TEST_ARGS[@]}"
step throughput 150 "$LOGS/throughput.txt" "$PY" benchmarks/throughput.py "${BENCH_ARGS[@]}" ||
  # the fused kernels failed (OptiX: several pipelines in one kernel?): the fallback's numbers
  step throughput-one-scene-per-kernel 120 "$LOGS/throughput_fallback.txt" \
    "$PY" benchmarks/throughput.py "${BENCH_ARGS[@]}" --one-scene-per-kernel

# ---- The report (stdout and the file); its exit status is the check's ----
echo "== report ($REPORT; logs $LOGS)"
(cd "$ROOT" && "$PY" tools/gpu_report.py --variant "$VARIANT" --logs "$LOGS" --report "$REPORT")
