#!/usr/bin/env bash
# The MuJoCo Warp backend's GPU check (issue 36), run on the device machine through the device tool's
# `run`, with the parts that `python bench/gpu_pack.py` wrote here (it prints the calls):
#   bash bench/gpu_check.sh stash   # every call but the last: keep this call's part on the machine
#   bash bench/gpu_check.sh run     # the last: unpack every part, run bench_backend.py on the GPU
# The run writes docs/PERFORMANCE.md's Warp section there and copies it, the JSON line and the log
# to $OUT, which comes back. On an H100 at commit 7115e0b (docs/results/gpu_backend) the run,
# both CUDA-graph modes, took 354 s of the call's 600 s, 131 s of it compiling Warp's kernels. It needs
# nvidia-smi (the machine's description comes first). GPU_CHECK_DEVICE=cpu GPU_CHECK_ARGS='--worlds 4
# --quick --json' runs the benchmark on Warp's CPU device instead, on a machine with nvidia-smi and a
# pack that keeps that device (gpu_pack.py --python 3.11 --cpu-device).
# With a dataset at .gpu/demos/demos.npz (carry .gpu/demos with the last call), NIRL's default
# training runs too (bench/bench_warp_training.py): on the CPU backend on one core while the
# benchmark runs (a same-machine reference), then on Warp's GPU worlds for at most
# GPU_CHECK_TRAIN_S seconds (default 230); their logs come back as train_cpu.log and train_warp.log,
# and the benchmark's limit, GPU_CHECK_LIMIT_S, defaults to 310 s instead of 520 so that both fit
# in one 600 s call (on the H200 the benchmark then stops in its agreement: give it fewer world
# counts). A stopped Warp training continues with bench_warp_training.py --resume --out /tmp/train-warp.
set -euo pipefail
verb=${1:?stash or run}
mkdir -p .gpu-stash
cp .gpu/p*/part.* .gpu-stash/
ls -l .gpu-stash
[ "$verb" = stash ] && exit 0
[ "$verb" = run ] || { echo "error: unknown verb $verb; accepted: stash, run" >&2; exit 2; }

want=$(cat .gpu/p*/parts | head -n 1)
have=$(ls .gpu-stash/part.* | wc -l)
if [ "$have" != "$want" ]; then
  echo "error: $have of $want parts on this machine (a fresh machine has lost the stash): make every call again, in a row" >&2
  exit 3
fi
site=/tmp/gpu-site
rm -rf "$site" && mkdir -p "$site"
cat .gpu-stash/part.* | python3 -c "import sys, tarfile; tarfile.open(fileobj=sys.stdin.buffer, mode='r|xz').extractall(sys.argv[1])" "$site"
export PYTHONPATH="$site:$PWD" MUJOCO_GL=disable  # no rendering: no EGL needed
out=${OUT:-/tmp/gpu-out}
mkdir -p "$out"
{ nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv; python3 --version
  python3 -c "import mujoco, warp, mujoco_warp, dm_control; print('mujoco', mujoco.__version__, 'warp', warp.__version__)"
} 2>&1 | tee "$out/machine.txt"
# Warp's compiled kernels from an earlier check (about 150 s of compiling saved), if one came back
# and was put in .gpu/cache (carry it with the last call): keyed by each kernel's source, so a stale
# entry is only never used.
cache=$HOME/.cache/warp
if [ -f .gpu/cache/warp-cache.tgz ]; then mkdir -p "$cache" && tar xzf .gpu/cache/warp-cache.tgz -C "$cache"; fi
demos=.gpu/demos/demos.npz
limit=520
if [ -f "$demos" ]; then
  limit=310
  rm -rf /tmp/train-cpu /tmp/train-warp  # a warm machine keeps an earlier call's runs
  OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 timeout 500 python3 bench/bench_warp_training.py --demos "$demos" \
    --out /tmp/train-cpu --backend cpu > "$out/train_cpu.log" 2>&1 &
fi
# Stopped before the call's limit so that what it wrote (the section is written once the agreement
# is in, before the launch-by-launch timings) still comes back.
timeout "${GPU_CHECK_LIMIT_S:-$limit}" python3 bench/bench_backend.py --device "${GPU_CHECK_DEVICE:-cuda}" \
  ${GPU_CHECK_ARGS:---json} 2>&1 | tee "$out/bench_backend.log" || echo "bench_backend.py stopped: rc $?" >&2
tail -n 1 "$out/bench_backend.log" > "$out/bench_backend.json"
cp docs/PERFORMANCE.md "$out/PERFORMANCE.md"
if [ -f "$demos" ]; then
  timeout "${GPU_CHECK_TRAIN_S:-230}" python3 bench/bench_warp_training.py --demos "$demos" --out /tmp/train-warp \
    --backend warp --device cuda --worlds 10 2>&1 | grep --line-buffered -v '^Module ' | tee "$out/train_warp.log" || true
  wait  # the CPU training (it ends well before: about 3 minutes on one core)
fi
# The kernel cache back, where it fits in what a call returns (16 MiB a file).
tar czf /tmp/warp-cache.tgz -C "$cache" . 2>/dev/null || true
if [ -f /tmp/warp-cache.tgz ] && [ "$(stat -c %s /tmp/warp-cache.tgz)" -le 16000000 ]; then
  cp /tmp/warp-cache.tgz "$out/warp-cache.tgz"
fi
ls -l /tmp/warp-cache.tgz 2>/dev/null || true
