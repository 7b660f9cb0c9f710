#!/usr/bin/env bash
# The whole suite (.ci/run) from a fresh clone, several times in a row, with a CPU hog on every core
# beside it, as a laptop running other programs would be. Every run must pass.
#
#   bash tools/stress_suite.sh [runs=3] [hogs=number of cores]
#
# Prints one line per run (passed/failed, minutes) and a last line `stress_suite_failed_runs: N`;
# each run's output is kept in the clone's folder (its path is printed).
set -uo pipefail
RUNS=${1:-3}
HOGS=${2:-$(nproc)}
SOURCE=$(cd "$(dirname "$0")/.." && pwd)
WORK=$(mktemp -d -t commission-stress-XXXXXX)

hog_pids=()
for _ in $(seq "$HOGS"); do
    python3 -c "while True: pass" &
    hog_pids+=($!)
done
trap 'kill "${hog_pids[@]}" 2>/dev/null; pip install -q --no-deps -e "$SOURCE" >/dev/null 2>&1' EXIT

failed=0
for run in $(seq "$RUNS"); do
    clone="$WORK/run-$run"
    git clone -q "$SOURCE" "$clone"
    start=$(date +%s)
    if (cd "$clone" && bash .ci/run) >"$clone.log" 2>&1; then verdict=passed; else verdict=FAILED; failed=$((failed + 1)); fi
    minutes=$(awk "BEGIN {printf \"%.1f\", ($(date +%s) - $start) / 60}")
    echo "run $run: $verdict in $minutes min with $HOGS CPU hogs ($(tail -1 "$clone.log"); log $clone.log)"
done
echo "stress_suite_failed_runs: $failed"
exit "$failed"
