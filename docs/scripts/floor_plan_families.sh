#!/usr/bin/env bash
# Success per floor-plan family of tasks/structured.toml (N arenas each, default 20; test seed 0 for
# the policies, demonstration seed 7 for the sensor expert, so its arenas differ): a trained run's
# policy, and unless REFERENCES=0 the rule, always forward and the sensor expert.
# The suites measure the same as an axis of an experiment (`family` in tasks/suites/transfer.toml, every
# method, paired test arenas, intervals); this script stays for the tables of ALGORITHM.md that cite it.
# Usage: bash docs/scripts/floor_plan_families.sh RUN [N]     (from any directory; nirl-mj on PATH
# or in the checkout's .venv). ALGORITHM.md's tables name the runs they used.
set -euo pipefail
run=$(realpath "$1")
N=${2:-20}
cd "$(dirname "$0")/../.."
nirl=$(command -v nirl-mj || echo .venv/bin/nirl-mj)
rate() { tail -n1 | python3 -c "import json,sys; print(json.load(sys.stdin)['success_rate'])"; }
for fam in corridors pockets clusters blocks rooms slalom; do
  set_=(--task tasks/structured.toml --set arena.floor_plan=$fam)
  line="$fam run=$("$nirl" eval --run "$run" "${set_[@]}" --tests "$N" --json --quiet --overwrite | rate)"
  if [ "${REFERENCES:-1}" != 0 ]; then
    r=$("$nirl" eval --policy rule "${set_[@]}" --tests "$N" --json --quiet | rate)
    f=$("$nirl" eval --policy forward "${set_[@]}" --tests "$N" --json --quiet | rate)
    s=$("$nirl" demos --expert sensor "${set_[@]}" --episodes "$N" --seed 7 --workers 1 \
      --out "/tmp/fam-$fam.npz" --overwrite --json --quiet | rate)
    line="$line rule=$r forward=$f sensor=$s"
  fi
  echo "$line"
done
