#!/usr/bin/env bash
# Keeps a finished main job's results in docs/results/main_job/: results.json, report.md and its
# figures, experiment.json, and the test episodes (tests/METHOD.npz, the dataset format) that the
# report's path and SCT columns are computed from. Then the docs' tables: python docs/scripts/render_docs.py.
# Usage: bash docs/scripts/publish_main_job.sh [RUN]   (default runs/main, what `nirl-mj run` writes)
set -euo pipefail
cd "$(dirname "$0")/../.."
run=${1:-runs/main}
[ -f "$run/report.md" ] || { echo "$run: no report.md; run nirl-mj run first" >&2; exit 2; }
out=docs/results/main_job
mkdir -p "$out"
cp "$run/results.json" "$run/report.md" "$run/experiment.json" "$out/"
cp "$run"/*.png "$out/"
mkdir -p "$out/tests"
cp "$run"/tests/*.npz "$out/tests/"
echo "$out: results.json, report.md, experiment.json and the report's figures"
