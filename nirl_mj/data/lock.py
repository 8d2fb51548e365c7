"""One writer per output directory: an advisory lock beside it.

``with DirectoryLock(path, what):`` holds an exclusive ``flock`` on ``.NAME.lock`` in the parent
of ``path`` (beside the directory, so that the directory's own contents stay what its commands
write), with the holder's process id in it, and removes it when done. A second writer is refused at
once with one line naming that process. The operating system releases the lock when its process
ends, however it ends (kill -9 too), so a lock file left by a dead process is simply taken over, and
the temporary file such a writer left beside a file it was writing (``data.atomic``) is deleted.
"""

from __future__ import annotations

import fcntl
import functools
import os
import sys
from collections.abc import Callable
from pathlib import Path

from nirl_mj.data.atomic import leftover_temporaries_of


class LockedError(RuntimeError):
    """Another live process is writing the directory."""


class DirectoryLock:
    """An exclusive lock on writing ``path`` (a directory, or a file such as a dataset)."""

    def __init__(self, path: str | os.PathLike, what: str = "output", wait: bool = False) -> None:
        """``wait``: block until the holder releases it instead of refusing (for a short update of
        one file, such as a run's ``eval.json``, that many processes may make)."""
        self.path = Path(path).resolve()
        self.what = what
        self.wait = wait
        self.lock_file = self.path.parent / f".{self.path.name}.lock"
        self._fd: int | None = None
        self._made: list[Path] = []  # the folders the lock file needed, deepest first

    def acquire(self) -> DirectoryLock:
        try:
            missing = self.lock_file.parent
            while not missing.exists():
                self._made.append(missing)
                missing = missing.parent
            return self._acquire()
        except PermissionError as exc:
            self._remove_made()
            raise PermissionError(
                f"cannot write {self.path}: its lock {self.lock_file} (in the output's "
                f"parent directory) cannot be written: {exc.strerror}"
            ) from None
        except BaseException:
            self._remove_made()
            raise

    def _remove_made(self) -> None:
        """Removes the folders made for the lock file while they are empty (a command refused under the
        lock leaves none behind; an output written there keeps them)."""
        for folder in self._made:
            try:
                folder.rmdir()
            except OSError:
                break
        self._made = []

    def _acquire(self) -> DirectoryLock:
        while True:
            # again each time: a releasing holder may have removed the folders it made for the lock
            self.lock_file.parent.mkdir(parents=True, exist_ok=True)
            try:
                fd = os.open(self.lock_file, os.O_RDWR | os.O_CREAT, 0o644)
            except FileNotFoundError:  # removed between the two calls: make it again
                continue
            try:
                if self._take(fd):
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, str(os.getpid()).encode(), 0)
                    self._fd = fd
                    # every writer of the path holds this lock: a temporary of it now is a killed one's
                    for leftover in leftover_temporaries_of(self.path):
                        leftover.unlink(missing_ok=True)
                    return self
            except BaseException:
                os.close(fd)  # an error never leaves the descriptor open (and so the lock held)
                raise
            os.close(fd)

    def _take(self, fd: int) -> bool:
        """Locks ``fd``; False if its file is no longer the lock file (a releasing holder removed it:
        the next attempt opens the new one)."""
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
            if self.wait:  # said, so that a wait behind a stopped process is not a silent hang
                print(f"waiting for process {holder} (another nirl-mj {self.what}) to finish writing "
                      f"{self.path}", file=sys.stderr)  # fmt: skip
                fcntl.flock(fd, fcntl.LOCK_EX)
                return self._current(fd)
            raise LockedError(
                f"{self.path} is being written by process {holder} (another nirl-mj "
                f"{self.what}); wait for it to end, or choose another output"
            ) from None
        return self._current(fd)

    def _current(self, fd: int) -> bool:
        """Whether the locked ``fd`` is still the lock file (not one a releasing holder removed)."""
        try:
            return os.stat(self.lock_file).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            return False

    def release(self) -> None:
        """Removes the lock file (while still holding it, so no one else holds a removed one) and
        unlocks."""
        if self._fd is not None:
            self.lock_file.unlink(missing_ok=True)
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None
        self._remove_made()

    def __enter__(self) -> DirectoryLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def writes(what: str) -> Callable[[Callable], Callable]:
    """Decorates a function whose first argument is the directory it writes: it runs holding that
    directory's :class:`DirectoryLock` (``what`` names the command in the refusal)."""

    def decorate(fn: Callable) -> Callable:
        @functools.wraps(fn)
        def locked(path: str | os.PathLike, *args, **kwargs):
            with DirectoryLock(path, what):
                return fn(path, *args, **kwargs)

        return locked

    return decorate


def process_folder(root: str | os.PathLike, prefix: str) -> Path:
    """A new folder ``root/PREFIX<pid>-<random>`` owned by this process, after removing the folders of
    that prefix whose process has ended (a killed process runs no clean-up)."""
    import secrets
    import shutil

    root = Path(root)
    for folder in root.glob(f"{prefix}*"):
        pid = folder.name[len(prefix) :].split("-", 1)[0]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)
    folder = root / f"{prefix}{os.getpid()}-{secrets.token_hex(4)}"
    folder.mkdir(parents=True)
    return folder


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's: alive
        return True
    return True
