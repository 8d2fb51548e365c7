#!/usr/bin/env bash
# Writes each suite's tables from the cells finished so far (nirl-mj suite --report) and keeps them in
# docs/results/suites/: NAME.csv (the tidy rows), NAME.md (the tables), NAME-AXIS.png (the curves),
# NAME.experiment.json (the identity). Then the reading of docs/RESULTS.md, "Suites":
# python docs/scripts/render_docs.py. Usage: bash docs/scripts/publish_suites.sh [NAME...]
# (default: demos quality transfer; each from runs/NAME, the suite's default output).
set -euo pipefail
cd "$(dirname "$0")/../.."
nirl=$(command -v nirl-mj || echo .venv/bin/nirl-mj)
mkdir -p docs/results/suites
for name in "${@:-demos quality transfer}"; do
  for suite in $name; do
    [ -d "runs/$suite" ] || { echo "runs/$suite: not computed here; skipped" >&2; continue; }
    "$nirl" suite --task "tasks/suites/$suite.toml" --report --quiet > /dev/null
    cp "runs/$suite/suite.csv" "docs/results/suites/$suite.csv"
    cp "runs/$suite/experiment.json" "docs/results/suites/$suite.experiment.json"
    md=$(cat "runs/$suite/suite.md")
    for png in runs/"$suite"/*.png; do
      axis=$(basename "$png" .png)
      cp "$png" "docs/results/suites/$suite-$axis.png"
      md=${md//"]($axis.png)"/"]($suite-$axis.png)"}
    done
    printf '%s\n' "$md" > "docs/results/suites/$suite.md"
    echo "docs/results/suites/$suite.{csv,md,experiment.json} and its PNGs"
  done
done
