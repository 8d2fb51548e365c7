"""Atomic file writes: a reader sees the old file or the new one, never a part.

Every writer here goes through :class:`AtomicFile`: a temporary file in the
target's directory (same file system, so the final rename is atomic), flushed to
disk and moved over the target, or deleted if anything fails. The temporary file
gets the permissions ``open()`` would give (not mkstemp's private 0600), and
those survive the rename. Without ``overwrite`` the move refuses a target that
exists, even one that appeared while the file was being written.
"""

from __future__ import annotations

import os
import re
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import IO

import numpy as np

EXISTS = "already exists; pass overwrite=True (or choose another path) to replace it"
"""Default refusal (after the path) when a target exists and ``overwrite`` is False."""


def refuse_existing(path: str | os.PathLike, overwrite: bool, refusal: str = EXISTS) -> None:
    """Raises ``FileExistsError("<path> <refusal>")`` if ``path`` exists and not ``overwrite``."""
    if not overwrite and Path(path).exists():
        raise FileExistsError(f"{path} {refusal}")


class AtomicFile:
    """A temporary file ``tmp`` next to ``path`` that :meth:`commit` moves into place and
    :meth:`discard` deletes.

    For writers that want a file name (ffmpeg, Pillow, Rerun, ``np.savez``): write to
    ``tmp``, then commit. As a context manager it commits when the block ends normally and
    discards on any exception (KeyboardInterrupt included)::

        with AtomicFile(out, ".png", overwrite=False) as target:
            image.save(target.tmp)

    ``suffix`` ends the temporary name (some writers pick a format by extension).
    Refuses an existing ``path`` unless ``overwrite`` (message ``"<path> <refusal>"``),
    both here and at :meth:`commit`.
    """

    def __init__(
        self, path: str | os.PathLike, suffix: str = "", overwrite: bool = True, refusal: str = EXISTS
    ) -> None:
        self.path = Path(path)
        self._overwrite, self._refusal = overwrite, refusal
        refuse_existing(self.path, overwrite, refusal)
        self.tmp = _create_temporary(self.path, suffix)

    def commit(self) -> Path:
        """Flushes ``tmp`` to disk and moves it to ``path``; returns ``path``."""
        try:
            _fsync_file(self.tmp)
            if self._overwrite:
                os.replace(self.tmp, self.path)
            else:
                _link_no_clobber(self.tmp, self.path, self._refusal)
        finally:
            self.tmp.unlink(missing_ok=True)  # not discard(): a subclass may do more there
        _fsync_directory(self.path.parent)
        return self.path

    def discard(self) -> None:
        """Deletes ``tmp`` (if it is still there)."""
        self.tmp.unlink(missing_ok=True)

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.discard()


_TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{8}\.tmp[^/]*$")  # the names _create_temporary gives


def leftover_temporaries(directory: str | os.PathLike) -> list[Path]:
    """Temporary files of this module's writers in ``directory``: left there only by a process
    killed while writing (a live writer removes its own), so safe to delete when no writer runs."""
    directory = Path(directory)
    if not directory.is_dir():
        return []
    return sorted(p for p in directory.iterdir() if p.is_file() and _TEMPORARY.match(p.name))


def leftover_temporaries_of(path: str | os.PathLike) -> list[Path]:
    """The temporary files of writes of ``path`` itself (beside it): left only by a writer killed while
    writing, so safe to delete by the holder of ``path``'s :class:`~nirl_mj.data.lock.DirectoryLock`."""
    path = Path(path)
    own = re.compile(rf"^\.{re.escape(path.name)}\.[0-9a-f]{{8}}\.tmp[^/]*$")
    return [p for p in leftover_temporaries(path.parent) if own.match(p.name)]


def _create_temporary(path: Path, suffix: str) -> Path:
    """A new empty file ``.<name>.<random>.tmp<suffix>`` next to ``path``."""
    while True:
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp{suffix}"
        try:
            # Mode 0666 less the umask, as open() gives; O_EXCL: never someone else's file.
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise type(exc)(f"cannot write {path}: {exc.strerror or exc}") from None
        os.close(fd)
        return tmp


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _link_no_clobber(tmp: Path, path: Path, refusal: str) -> None:
    """Moves ``tmp`` to ``path`` unless ``path`` appeared meanwhile (hard link: atomic and
    fails on an existing target); falls back to a rename where the file system has no
    hard links."""
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise FileExistsError(f"{path} {refusal}") from None
    except OSError:
        refuse_existing(path, False, refusal)
        os.replace(tmp, path)
        return
    os.unlink(tmp)


def _fsync_directory(directory: Path) -> None:
    # Makes the rename itself durable; not possible on every platform.
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write(path: str | os.PathLike, mode: str, fill: Callable[[IO], None]) -> Path:
    with AtomicFile(path) as target, open(target.tmp, mode) as f:
        fill(f)
    return target.path


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Writes ``text`` to ``path`` atomically."""
    return _write(path, "w", lambda f: f.write(text))


def write_figure(path: str | os.PathLike, fig, metadata: dict[str, str] | None = None) -> Path:
    """Saves the matplotlib figure ``fig`` as a PNG at ``path`` atomically; ``metadata``: text chunks
    of the PNG (``Description``: what the figure was drawn from, for a test to compare)."""
    return _write(path, "wb", lambda f: fig.savefig(f, format="png", metadata=metadata))


def write_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> Path:
    """Writes ``arrays`` as an uncompressed NPZ to ``path`` atomically."""
    return _write(path, "wb", lambda f: np.savez(f, **arrays))
