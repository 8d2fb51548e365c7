#!/usr/bin/env bash
# Success per floor-plan family (20 arenas each; test seed 0 for the policies, demonstration seed 7
# for the sensor expert, so its arenas differ): the rule, always forward, the sensor expert, and the
# NIRL-q run 0 of tasks/ablations/nirl_inner.toml (trained on random arenas only). Needs that run.
cd /work/main
N=20
for fam in corridors pockets clusters blocks rooms slalom; do
  set_=(--task tasks/structured.toml --set arena.floor_plan=$fam)
  r=$(.venv/bin/nirl-mj eval --policy rule "${set_[@]}" --tests $N --json --quiet | tail -n1 | python3 -c "import json,sys; print(json.load(sys.stdin)['success_rate'])")
  f=$(.venv/bin/nirl-mj eval --policy forward "${set_[@]}" --tests $N --json --quiet | tail -n1 | python3 -c "import json,sys; print(json.load(sys.stdin)['success_rate'])")
  n=$(.venv/bin/nirl-mj eval --run runs/nirl_inner/runs/NIRL-q/0 "${set_[@]}" --tests $N --json --quiet | tail -n1 | python3 -c "import json,sys; print(json.load(sys.stdin)['success_rate'])")
  s=$(.venv/bin/nirl-mj demos --expert sensor "${set_[@]}" --episodes $N --seed 7 --workers 1 --out /tmp/fam-$fam.npz --overwrite --json --quiet | tail -n1 | python3 -c "import json,sys; print(json.load(sys.stdin)['success_rate'])")
  echo "$fam rule=$r forward=$f sensor=$s nirl_q=$n"
done
