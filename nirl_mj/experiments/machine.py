"""The machine a result was computed on, as far as its bits were seen to depend on it."""

from __future__ import annotations

from pathlib import Path


def platform_key() -> str:
    """The CPU's vendor and torch's CPU capability (``"AuthenticAMD/AVX2"``, say): the same code and
    seeds gave other bits on AVX2 and AVX512 machines (tests/test_digest.py). Library versions and
    builds matter too and are not in the key: pinned versions keep them apart."""
    import torch

    cpuinfo = Path("/proc/cpuinfo")
    lines = cpuinfo.read_text().splitlines() if cpuinfo.is_file() else []
    vendor = next(
        (line.split(":", 1)[1].strip() for line in lines if line.startswith("vendor_id")), "unknown"
    )
    return f"{vendor}/{torch.backends.cpu.get_cpu_capability()}"
