#!/usr/bin/env bash
# The timing-sensitive tests on a busy machine (issue #56): N processes spinning on the CPUs
# while pytest runs the tests that wait for processes, servers, zenoh routes and browsers,
# REPEAT times; fails if any run fails. Each run's pass count and duration are printed.
#
#   bash scripts/under_load.sh [PYTEST ARGS...]      e.g. -x, -k bridge, --timeout 900
#   N=4 REPEAT=1 bash scripts/under_load.sh          (defaults: N=2 busy processes, REPEAT=3)
#   TESTS="tests/test_bridge.py tests/test_foxglove.py" bash scripts/under_load.sh
#
# The busy processes are ended on any exit (trap), Ctrl-C included.
set -uo pipefail
cd "$(dirname "$0")/.."

N=${N:-2}
REPEAT=${REPEAT:-3}
PYTHON=${PYTHON:-.venv/bin/python}
export MUJOCO_GL=${MUJOCO_GL:-egl}
DEFAULT_TESTS="tests/test_cli_errors.py tests/test_bridge.py tests/test_bridge_faults.py
  tests/test_security_dashboard.py tests/test_security_teleop.py tests/test_dashboard.py
  tests/test_dashboard_results.py tests/test_foxglove.py tests/test_stream_ingest.py
  tests/test_web_ingest.py tests/test_recorder.py tests/test_ray_scale.py
  tests/test_teleop_entry.py tests/test_guards.py"
read -r -a TEST_FILES <<< "$(echo ${TESTS:-$DEFAULT_TESTS})"

if [ ! -x "$PYTHON" ]; then
  echo "under_load: no $PYTHON (make test creates .venv; or set PYTHON=...)" >&2
  exit 2
fi

busy=()
stop_load() {
  for pid in "${busy[@]}"; do kill "$pid" 2>/dev/null; done
  for pid in "${busy[@]}"; do wait "$pid" 2>/dev/null; done
  busy=()
}
trap stop_load EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

for _ in $(seq "$N"); do
  "$PYTHON" -c 'while True: pass' &
  busy+=("$!")
done
echo "under_load: $N busy processes (${busy[*]}) on $(nproc) CPUs; $REPEAT run(s) of ${#TEST_FILES[@]} files"

log=$(mktemp)
failed=0
summaries=()
for run in $(seq "$REPEAT"); do
  start=$(date +%s%N)
  "$PYTHON" -m pytest -q "${TEST_FILES[@]}" "$@" 2>&1 | tee "$log"
  rc=${PIPESTATUS[0]}
  ms=$(( ($(date +%s%N) - start) / 1000000 ))
  # pytest's closing line, e.g. "95 passed, 3 skipped in 201.33s"
  result=$(grep -E '[0-9]+ (passed|failed|error|errors|skipped)' "$log" | tail -n 1 \
           | sed -E 's/=+//g; s/^ +| +$//g')
  line=$(printf 'run %d/%d: %s (exit %d), %d.%d s wall' "$run" "$REPEAT" "${result:-no result}" \
         "$rc" $((ms / 1000)) $((ms % 1000 / 100)))
  summaries+=("$line")
  echo "under_load: $line"
  [ "$rc" -eq 0 ] || failed=1
done
rm -f "$log"

echo "under_load: summary ($N busy processes, load average $(cut -d' ' -f1-3 /proc/loadavg))"
printf '  %s\n' "${summaries[@]}"
if [ "$failed" -ne 0 ]; then
  echo "under_load: FAILED: at least one run did not pass" >&2
  exit 1
fi
echo "under_load: all $REPEAT run(s) passed"
