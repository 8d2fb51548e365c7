#!/usr/bin/env bash
# Keeps a finished main job's results in docs/results/main_job/: results.json, report.md and its
# figures, experiment.json, the test episodes (tests/METHOD.npz, the dataset format) that the
# report's path and SCT columns are computed from, and NIRL's run record, metrics and reward
# (nirl/: what the training figures are drawn from; published since 2026-11-30).
# Then the docs' tables: python docs/scripts/render_docs.py.
# Usage: bash docs/scripts/publish_main_job.sh [RUN]   (default runs/main, what `nirl-mj run` writes)
set -euo pipefail
cd "$(dirname "$0")/../.."
run=${1:-runs/main}
[ -f "$run/report.md" ] || { echo "$run: no report.md; run nirl-mj run first" >&2; exit 2; }
out=docs/results/main_job
stage=docs/results/.main_job.staging
rm -rf "$stage" && mkdir -p "$stage/tests"
cp "$run/results.json" "$run/report.md" "$run/experiment.json" "$run"/*.png "$stage/"
cp "$run"/tests/*.npz "$stage/tests/"
mkdir -p "$stage/nirl" && cp "$run"/runs/NIRL/0/{run.json,metrics.jsonl,reward.json} "$stage/nirl/"
# the published folder is replaced whole (no stale file of an older job stays), by renames
rm -rf "$out.old" && { [ ! -d "$out" ] || mv "$out" "$out.old"; } && mv "$stage" "$out" && rm -rf "$out.old"
echo "$out: results.json, report.md, experiment.json, the report's figures, tests/ and nirl/"
