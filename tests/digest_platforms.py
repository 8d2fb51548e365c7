"""The tiny run's digest (tests/test_digest.py) for every pinned platform, from one AMD AVX512 machine.

    .venv/bin/python tests/digest_platforms.py [--only NAME ...]

The bits of the tiny run were seen to depend on the kernels that torch, MKL, numpy and OpenBLAS
pick at run time (tests/test_digest.py). Each library can be told by an environment variable to
pick an older CPU's kernels, or another of its own, so one AMD machine with AVX512 stands in for
the pinned machines: each entry below runs the tiny run in a process of its own with the kernel
variables of this process removed and the entry's set, checks that the child reports the entry's
platform key and OpenBLAS kernels (a machine that cannot stand in for an entry stops the tool),
and prints the digest. Checked on 2026-11-30 on a Zen 5 machine (cpu family 26) whose environment
also held ``OPENBLAS_L2_SIZE=512``, with the same pinned library versions: at 3513ea6 the three
entries gave the three digests pinned then (AVX2 3fffecc..., AVX512-SkylakeX dc23578...,
AVX512-Haswell 641f16e...), so a change meant to alter results can be pinned for all of them at
once. The AVX512 machines differed only in OpenBLAS's kernels: SkylakeX is what it picks on these
AMD machines by itself, Haswell what the Zen 5 machine's environment chose
(``OPENBLAS_CORETYPE=Haswell``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

SELECTORS = ("ATEN_CPU_CAPABILITY", "MKL_ENABLE_INSTRUCTIONS", "NPY_DISABLE_CPU_FEATURES",
             "OPENBLAS_CORETYPE")  # fmt: skip
"""The variables that choose kernels: removed from the child's environment before an entry's are set."""

PLATFORMS = {
    # the AVX2 machine of CI: torch's AVX2 kernels, MKL's, numpy's without its AVX512 dispatch,
    # OpenBLAS's Haswell kernels (what it picks on an AVX2 EPYC)
    "AVX2": ("AuthenticAMD/AVX2", "Haswell", {
        "ATEN_CPU_CAPABILITY": "avx2",
        "MKL_ENABLE_INSTRUCTIONS": "AVX2",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4,AVX512_ICL,AVX512_SPR",
        "OPENBLAS_CORETYPE": "Haswell",
    }),
    # the first AVX512 machine (2026-11-29): OpenBLAS's own choice there, SkylakeX
    "AVX512-SkylakeX": ("AuthenticAMD/AVX512", "SkylakeX", {"OPENBLAS_CORETYPE": "SkylakeX"}),
    # the Zen 5 machine (2026-11-30), whose environment sets OPENBLAS_CORETYPE=Haswell
    "AVX512-Haswell": ("AuthenticAMD/AVX512", "Haswell", {"OPENBLAS_CORETYPE": "Haswell"}),
}  # fmt: skip
"""Each pinned machine: the platform key and OpenBLAS kernels its child must report, and the
variables set for it."""

_CHILD = """
import ctypes, sys, tempfile
from pathlib import Path
sys.path[:0] = [{tests!r}, {root!r}]  # this checkout's code, whatever is installed
from test_digest import tiny_run_digest
from nirl_mj.experiments.machine import platform_key
import numpy
maps = open("/proc/self/maps").read().split()
blas = sorted({{p for p in maps if "openblas" in p and p.endswith(".so")}})
corename = ctypes.CDLL(blas[0]).scipy_openblas_get_corename64_ if blas else None
if corename is not None:
    corename.restype = ctypes.c_char_p
with tempfile.TemporaryDirectory() as tmp:
    digest = tiny_run_digest(Path(tmp))
print(platform_key(), corename().decode() if corename is not None else "unknown", digest)
"""


def digest_with(name: str) -> str:
    """The digest of the tiny run for platform ``name`` of :data:`PLATFORMS`, computed in a fresh
    process; stops (naming the platform) if the child is not that platform or the run fails."""
    key, kernels, variables = PLATFORMS[name]
    env = {k: v for k, v in os.environ.items() if k not in SELECTORS}
    env = {**env, "MUJOCO_GL": env.get("MUJOCO_GL", "egl"), **variables}
    tests = Path(__file__).resolve().parent
    code = _CHILD.format(tests=str(tests), root=str(tests.parent))
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{name}: the tiny run failed:\n{done.stderr[-3000:]}")
    got_key, got_kernels, digest = done.stdout.strip().splitlines()[-1].split()
    if (got_key, got_kernels) != (key, kernels):
        raise SystemExit(f"{name}: this machine ran it as {got_key} with OpenBLAS {got_kernels}, not {key} "
                         f"with {kernels}: it cannot stand in for that platform")  # fmt: skip
    return digest


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", default=None, help="platform names to run (default: all)")
    args = parser.parse_args()
    names = list(PLATFORMS) if not args.only else args.only
    unknown = [n for n in names if n not in PLATFORMS]
    if unknown:
        parser.error(f"unknown platform {unknown[0]!r}; accepted: {', '.join(PLATFORMS)}")
    for name in names:
        key, kernels, _ = PLATFORMS[name]
        print(f"{name} ({key}, OpenBLAS {kernels}): {digest_with(name)}", flush=True)


if __name__ == "__main__":
    main()
