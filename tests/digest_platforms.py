"""The tiny run's digest (tests/test_digest.py) of every pinned platform, from one AVX512 machine.

    .venv/bin/python tests/digest_platforms.py [--only KEY ...]

The bits of the tiny run were seen to depend on the kernels that torch, MKL, numpy and OpenBLAS
pick at run time for the CPU (tests/test_digest.py). Each of them can be told to pick an older
CPU's kernels by an environment variable, so a machine with AVX512 computes what the pinned
machines compute: each platform below runs the tiny run in a process of its own with its
variables set, and prints its platform key and digest. Checked on 2026-11-30 on the Zen 5 machine:
at 3513ea6 the three entries gave the three digests pinned then, each the one its machine had
given (AVX2 3fffecc..., AVX512-SkylakeX dc23578..., AVX512-Zen 641f16e...), so a change that is
meant to alter results can be pinned for all of them at once. A machine without
AVX512 cannot stand in for those with it.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

PLATFORMS = {
    # the AVX2 machine of CI: torch's AVX2 kernels, MKL's, numpy's without its AVX512 dispatch,
    # OpenBLAS's Zen (Haswell) kernels
    "AVX2": {
        "ATEN_CPU_CAPABILITY": "avx2",
        "MKL_ENABLE_INSTRUCTIONS": "AVX2",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4,AVX512_ICL,AVX512_SPR",
        "OPENBLAS_CORETYPE": "Zen",
    },
    # the first AVX512 machine (2026-11-29), on which OpenBLAS picked its SkylakeX kernels
    "AVX512-SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
    # the Zen 5 machine (cpu family 26), on which OpenBLAS picks its Zen kernels
    "AVX512-Zen": {"OPENBLAS_CORETYPE": "Zen"},
}
"""What each pinned machine's digest is computed with: the variables set for its process."""

_CHILD = """
import sys, tempfile
from pathlib import Path
sys.path[:0] = [{tests!r}, {root!r}]  # this checkout's code, whatever is installed
from test_digest import tiny_run_digest
from nirl_mj.experiments.machine import platform_key
with tempfile.TemporaryDirectory() as tmp:
    print(platform_key(), tiny_run_digest(Path(tmp)))
"""


def digest_with(variables: dict[str, str]) -> str:
    """``"KEY DIGEST"`` of the tiny run in a fresh process with ``variables`` set."""
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), **variables}
    tests = Path(__file__).resolve().parent
    code = _CHILD.format(tests=str(tests), root=str(tests.parent))
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"the tiny run failed:\n{done.stderr[-3000:]}")
    return done.stdout.strip().splitlines()[-1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", default=None, help="platform names to run (default: all)")
    args = parser.parse_args()
    names = list(PLATFORMS) if not args.only else args.only
    unknown = [n for n in names if n not in PLATFORMS]
    if unknown:
        parser.error(f"unknown platform {unknown[0]!r}; accepted: {', '.join(PLATFORMS)}")
    for name in names:
        print(f"{name}: {digest_with(PLATFORMS[name])}", flush=True)


if __name__ == "__main__":
    main()
