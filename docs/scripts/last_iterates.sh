#!/usr/bin/env bash
# The last iterate of every run of a compare experiment, on the same 100 test arenas as the
# experiment's table (run R is tested with seed R): is selection a safeguard or the result?
# For experiments on the development domain (test_domain = "test") with one set of demonstrations,
# as before 2026-11-26 (`nirl-mj eval` draws from that domain); tasks/table1.toml has a NIRL-last
# row instead.
# Usage: [JOBS=2] bash docs/scripts/last_iterates.sh OUT METHOD [METHOD ...]   (OUT: the experiment's
# --out; from any directory, nirl-mj on PATH or in the checkout's .venv; JOBS: evaluations at once)
# Prints one line per method: the last iterates' success per run (in run order) and their average (percent).
set -euo pipefail
out=$(realpath "$1")
shift
cd "$(dirname "$0")/../.."
nirl=$(command -v nirl-mj || echo .venv/bin/nirl-mj)
export nirl
last_iterate() {  # RUN_DIR -> "R RATE"
  local r line
  r=$(basename "$1")
  line=$("$nirl" eval --run "$1" --which last --seed "$r" --tests 100 --quiet --json --overwrite | tail -1)
  echo "$r $(python3 -c 'import json, sys; print(round(100 * json.loads(sys.argv[1])["success_rate"]))' "$line")"
}
export -f last_iterate
for method in "$@"; do
  mapfile -t rates < <(printf '%s\n' "$out/runs/$method"/*/ | xargs -P "${JOBS:-1}" -I{} bash -c 'last_iterate "$1"' _ {} \
    | sort -n | cut -d' ' -f2)
  avg=$(python3 -c 'import sys; v = [float(x) for x in sys.argv[1:]]; print(f"{sum(v) / len(v):.1f}")' "${rates[@]}")
  echo "$method: last iterate ${rates[*]} -> average $avg %"
done
