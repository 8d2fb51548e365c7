"""Atomic file writes: a reader sees the old file or the new one, never a part.

Each writes a temporary file in the target's directory, flushes it to disk and
renames it over the target (``os.replace`` is atomic on one file system).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO

import numpy as np


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


FILE_MODE = 0o666 & ~_umask()  # what open() would give: mkstemp's files are private (0600)


def _write(path: str | os.PathLike, mode: str, fill: Callable[[IO], None]) -> Path:
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        os.fchmod(fd, FILE_MODE)
        with os.fdopen(fd, mode) as f:
            fill(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Writes ``text`` to ``path`` atomically."""
    return _write(path, "w", lambda f: f.write(text))


def write_figure(path: str | os.PathLike, fig) -> Path:
    """Saves the matplotlib figure ``fig`` as a PNG at ``path`` atomically."""
    return _write(path, "wb", lambda f: fig.savefig(f, format="png"))


def write_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> Path:
    """Writes ``arrays`` as an uncompressed NPZ to ``path`` atomically."""
    return _write(path, "wb", lambda f: np.savez(f, **arrays))
