"""Pack what ``bench/bench_backend.py --device cuda`` needs for the device machine, in parts that fit.

The device machine (the ``device`` tool's ``run``) has Python 3.12 with NumPy, SciPy, PyTorch and
most of the scientific stack, but not MuJoCo, dm_control or MuJoCo Warp, and it reaches nothing
outside itself; a call carries at most 64 MiB of the working tree. ``warp-lang``'s wheel alone is
149 MB. This script downloads the Python 3.12 wheels of the versions installed here, unpacks them
without what the benchmark never imports (dm_control's suite and locomotion assets, MuJoCo's
experimental studio, Warp's tests, examples and CPU-device compiler), and writes them as one
xz-compressed tar cut into parts of at most ``--part-mib`` MiB: ``.gpu/p1/part.01``,
``.gpu/p2/part.02``, ... (``.gpu/`` is git-ignored). It then prints the calls to make, one per
part, each carrying its own folder: every call but the last only stashes its part on the machine
(``bash bench/gpu_check.sh stash``), and the last unpacks them all and runs the benchmark
(``bash bench/gpu_check.sh run``). The machine is
given back 30 seconds after a call ends, and a fresh one has lost the stash: make the calls one
right after the other.

    python bench/gpu_pack.py       # 232 MiB of wheels -> 93 MiB in 3 parts; ~3 min (xz on one core)

These parts and ``bench/gpu_check.sh`` ran on an H100 at commits 2b1cbc8, d1a32e9 and 7115e0b, and
on an H200 at 4144f67 (docs/results/gpu_backend).
"""

from __future__ import annotations

import argparse
import io
import lzma
import shutil
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from importlib.metadata import version
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("mujoco", "dm-control", "mujoco-warp", "warp-lang", "dm-env", "dm-tree", "labmaze", "pyopengl",
            "glfw", "websockets")  # fmt: skip
"""What the benchmark imports that the device image lacks (its list: the device tool's KINDS.md)."""
PRUNED = ("dm_control/suite/", "dm_control/locomotion/", "mujoco/experimental/", "warp/tests/",
          "warp/examples/")  # fmt: skip
"""Folders the benchmark never imports: 150 MB of the 430 MB unpacked."""
CPU_DEVICE = ("warp/bin/warp-clang.so",)
"""Warp's compiler for its CPU device (69 MB): Warp loads it only if present, and the GPU check
runs kernels on CUDA alone (its CPU reference is the dm_control task). Kept with ``--cpu-device``."""
KEPT = ("cache", "demos")
"""Folders of ``.gpu/`` the last call carries beside its part, kept when the parts are made again:
Warp's kernel cache from an earlier check and a dataset for the NIRL training (gpu_check.sh)."""
PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_24_x86_64",
             "manylinux_2_17_x86_64", "manylinux2014_x86_64")  # fmt: skip


def download(dest: Path, python: str) -> list[Path]:
    """The wheels of :data:`PACKAGES`, at the versions installed here, for CPython ``python``."""
    pins = [f"{name}=={version(name)}" for name in PACKAGES]
    platforms = [arg for p in PLATFORMS for arg in ("--platform", p)]
    subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
                    "--python-version", python, *platforms, "-d", str(dest), *pins], check=True)  # fmt: skip
    return sorted(dest.glob("*.whl"))


def archive(wheels: list[Path], pruned: tuple[str, ...]) -> bytes:
    """One tar of the wheels' files less those under ``pruned``, xz-compressed at preset 9."""
    raw = io.BytesIO()
    with tarfile.open(fileobj=raw, mode="w") as tar:
        for wheel in wheels:
            with zipfile.ZipFile(wheel) as z:
                for info in z.infolist():
                    if info.is_dir() or info.filename.startswith(pruned):
                        continue
                    entry = tarfile.TarInfo(info.filename)
                    entry.size, entry.mode = info.file_size, 0o755 if info.filename.endswith(".so") else 0o644
                    with z.open(info) as f:
                        tar.addfile(entry, f)
    return lzma.compress(raw.getvalue(), preset=9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / ".gpu")
    parser.add_argument(
        "--part-mib",
        type=float,
        default=45.0,
        help="a part's size (the tracked tree, about 10 MB, travels with it: 64 MiB a call)",
    )
    parser.add_argument("--python", default="3.12", help="the device's Python (KINDS.md: 3.12.3)")
    parser.add_argument("--cpu-device", action="store_true", help="keep Warp's CPU device (a local try)")
    args = parser.parse_args()
    if args.out.exists():
        parts = [p for p in args.out.iterdir() if p.is_dir() and p.name[:1] == "p" and p.name[1:].isdigit()]
        if any(p not in parts and p.name not in KEPT for p in args.out.iterdir()):
            raise SystemExit(f"error: {args.out} holds more than this script's parts (p1/, p2/, ...), "
                             f"{' and '.join(f'{k}/' for k in KEPT)}; choose another --out")  # fmt: skip
        for folder in parts:  # this script's own earlier parts
            shutil.rmtree(folder)
    with tempfile.TemporaryDirectory() as tmp:
        wheels = download(Path(tmp), args.python)
        print(f"{len(wheels)} wheels, {sum(w.stat().st_size for w in wheels) / 2**20:.0f} MiB", flush=True)
        blob = archive(wheels, PRUNED if args.cpu_device else PRUNED + CPU_DEVICE)
    size = int(args.part_mib * 2**20)
    parts = [blob[i : i + size] for i in range(0, len(blob), size)]
    for i, part in enumerate(parts, 1):
        folder = args.out / f"p{i}"
        folder.mkdir(parents=True)
        (folder / f"part.{i:02d}").write_bytes(part)
        (folder / "parts").write_text(f"{len(parts)}\n")  # the last call checks that it has them all
    mib = len(blob) / 2**20
    print(f"{mib:.0f} MiB compressed, {len(parts)} parts under {args.out}; the calls, one after the other:")
    for i in range(1, len(parts) + 1):
        verb = "run" if i == len(parts) else "stash"
        carry = ", ".join(f'".gpu/{name}"' for name in (f"p{i}", *(KEPT if verb == "run" else ())))
        print(f'  run(command="bash bench/gpu_check.sh {verb}", carry=[{carry}], timeout_s=600)')
    print(
        "The last call returns warp-cache.tgz (Warp's kernels) where it fits: put it in .gpu/cache/; "
        "a dataset in .gpu/demos/demos.npz adds the NIRL trainings (nirl-mj demos --episodes 30 --out ...)"
    )


if __name__ == "__main__":
    main()
