"""Running independent cells of an experiment: in this process, on local processes, or on Ray.

A :class:`Cell` is a picklable module-level function with its arguments whose
result is JSON-able (a dict of numbers, strings, lists). :func:`run_cells` runs
a list of cells on one of three executors and returns every result by cell id:

- ``serial``: one after the other in this process;
- ``local``: ``workers`` spawned processes (default: all cores); spawn, not fork,
  so no MuJoCo or OpenGL state is inherited;
- ``ray``: Ray tasks of one CPU each, on the cluster at ``address`` or on a local
  one started with ``num_cpus=workers`` (``pip install 'nirl-mj[ray]'``).

Results do not depend on the executor or on ``workers``: a cell seeds itself from
its own arguments, never from worker state; torch runs one thread inside a cell
(a different thread count may reorder floating-point sums); and every result
goes through JSON, so what a serial run returns is what a stored cell reads back.

With a :class:`CellStore`, each finished cell's result is written atomically to
``DIR/<cell id>.json`` as soon as it arrives, and cells found there are not run
again: an interrupted experiment resumes where it stopped. A cell that raises,
or whose process dies, is tried again up to ``retries`` more times; one that
still fails is returned in :attr:`Report.failures` with its traceback (and is
not stored, so the next run tries it again), never silently dropped.
"""

from __future__ import annotations

import gc
import json
import multiprocessing
import os
import re
import shutil
import sys
import tempfile
import time
import traceback
from collections import Counter, deque
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, CancelledError, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nirl_mj.data.atomic import write_text

EXECUTORS = ("serial", "local", "ray")
RAY_MISSING = "the ray executor needs Ray: pip install 'nirl-mj[ray]' (or pip install 'ray>=2.9')"
_ID = re.compile(r"^[A-Za-z0-9_.=+-]+$")


def default_workers() -> int:
    """All cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


PERMANENT = ("MethodError: ", "ModuleNotFoundError: ")
"""A cell whose last error line holds one of these broke a method's rules (``experiments.plugins``) or
needs a package that is not installed: running it again cannot change that, so it is not retried. (A
stored run or dataset found damaged is retried: the same errors wrap a failed read, which may pass.)"""


class ExecutorError(RuntimeError):
    """An executor cannot run: unknown name, bad worker count, Ray missing or unreachable."""


@dataclass(frozen=True)
class Cell:
    """One independent unit of work: ``fn(*args)`` -> a JSON-able result.

    ``id`` names the cell's file in a :class:`CellStore` (letters, digits and ``_.=+-``).
    ``fn`` must be importable by name (a module-level function) for the process and Ray
    executors to send it to another interpreter.
    """

    id: str
    fn: Callable[..., Any]
    args: tuple = ()

    def __post_init__(self) -> None:
        if not _ID.match(self.id):
            raise ValueError(f"cell id {self.id!r}: use letters, digits and _ . = + - only")


@dataclass(frozen=True)
class Failure:
    """A cell that failed every attempt: the last error's one-line summary and traceback."""

    id: str
    error: str
    traceback: str
    attempts: int


@dataclass
class Report:
    """What :func:`run_cells` did. ``results`` are in the order of the cells given."""

    results: dict[str, Any] = field(default_factory=dict)
    failures: dict[str, Failure] = field(default_factory=dict)
    reused: list[str] = field(default_factory=list)  # read from the store, not run
    computed: list[str] = field(default_factory=list)  # run now
    seconds: dict[str, float] = field(default_factory=dict)  # wall time of each computed cell


class CellStore:
    """Finished cells as ``DIR/<id>.json`` files: ``{"id", "result", "seconds", "attempts", "platform"}``
    (``platform``: the machine that computed the cell, :func:`nirl_mj.experiments.machine.platform_key`,
    whose bits a result depends on; cells stored before it was recorded lack it)."""

    def __init__(self, directory: str | Path, check: Callable[[Any, str], str | None] | None = None) -> None:
        self.directory = Path(directory)
        self.check = check  # check(result, cell id): a stored result it finds wrong (a reason) is unfinished

    def path(self, cell_id: str) -> Path:
        return self.directory / f"{cell_id}.json"

    def load(self, cell_id: str) -> Any | None:
        """The stored result, or None if the cell has not finished (or its file is damaged,
        :meth:`problem`: it is computed again)."""
        return self._read(cell_id)[0]

    def problem(self, cell_id: str) -> str | None:
        """Why the file of ``cell_id`` holds no finished cell (unreadable, cut short, another cell's,
        or a result ``check`` finds wrong), or None if it does or there is no file."""
        return self._read(cell_id)[1]

    def _read(self, cell_id: str) -> tuple[Any | None, str | None]:
        path = self.path(cell_id)
        if not path.exists():
            return None, None
        try:
            record = json.loads(path.read_text())
            result = record["result"]
        except OSError as exc:
            return None, f"cannot be read ({exc.strerror or exc})"
        except ValueError:
            return None, "is not JSON (a write cut short?)"
        except (KeyError, TypeError):
            return None, "holds no result"
        if record.get("id", cell_id) != cell_id:  # another cell's record under this name (copied over)
            return None, f"holds cell {record.get('id')}"
        why = self.check(result, cell_id) if self.check is not None else None
        return (None, f"holds a result that cannot be this cell's: {why}") if why else (result, None)

    def save(self, cell_id: str, result: Any, seconds: float, attempts: int, platform: str = "") -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        record = {"id": cell_id, "result": result, "seconds": round(seconds, 3), "attempts": attempts}
        if platform:
            record["platform"] = platform
        write_text(self.path(cell_id), json.dumps(record, indent=1))


def call_cell(fn: Callable[..., Any], args: tuple) -> tuple[str, str, float, str]:
    """Runs one cell where it is sent; returns ("ok", result as JSON, seconds, platform) or
    ("error", traceback, seconds, platform), the platform being the worker's machine's
    (:func:`nirl_mj.experiments.machine.platform_key`). Errors travel as text: not every exception
    pickles."""
    import torch

    from nirl_mj.experiments.machine import platform_key

    threads, where = torch.get_num_threads(), platform_key()
    torch.set_num_threads(1)  # the same arithmetic whatever the executor (see the module doc)
    start = time.perf_counter()
    try:
        return "ok", json.dumps(fn(*args)), time.perf_counter() - start, where
    except Exception:
        return "error", traceback.format_exc(), time.perf_counter() - start, where
    finally:
        torch.set_num_threads(threads)


def unused_workers(executor: str, workers: int | None, address: str | None) -> str | None:
    """Why ``workers`` would be ignored (more than 1 for the serial executor, or any for a Ray cluster at
    ``address``, whose own CPUs bound the parallelism), or None when it is used or not given."""
    if workers is None:
        return None
    if executor == "serial" and workers != 1:
        return f"--workers {workers}: the serial executor runs every cell in this process; leave it out"
    if executor == "ray" and address:
        return (f"--workers {workers}: the Ray cluster at {address} runs as many cells as it has CPUs; "
                "--workers sizes a local cluster only: leave it out")  # fmt: skip
    return None


class Executor:
    """Runs lists of cells; keeps its processes (or its Ray connection) between :meth:`run` calls,
    so an experiment's phases pay the start-up once. Use as a context manager, or :meth:`close`.

    ``executor``: one of :data:`EXECUTORS`. ``workers``: processes (local) or CPUs of a local Ray
    cluster; default all cores. ``address``: an existing Ray cluster ("auto", "ray://host:10001",
    ...), whose own CPUs then bound the parallelism. ``retries``: further attempts of a failing cell.
    """

    def __init__(
        self,
        executor: str = "local",
        workers: int | None = None,
        address: str | None = None,
        retries: int = 2,
    ) -> None:
        if executor not in EXECUTORS:
            raise ExecutorError(f"unknown executor {executor!r}; accepted: {', '.join(EXECUTORS)}")
        if workers is not None and workers < 1:
            raise ExecutorError(f"workers must be >= 1, got {workers}")
        if retries < 0:
            raise ExecutorError(f"retries must be >= 0, got {retries}")
        self.kind, self.workers, self.address = executor, workers or default_workers(), address
        self.retries = retries
        self._backend = None  # started by the first cell to compute: a resumed run may need none

    def run(
        self,
        cells: Iterable[Cell],
        store: CellStore | None = None,
        on_done: Callable[[str, Any, Failure | None], None] | None = None,
        on_retry: Callable[[str, str], None] | None = None,
    ) -> Report:
        """Runs the cells not already in ``store``; returns every result by id and the failures.
        ``on_done(id, result, failure)`` is called as each cell finishes (result None on failure),
        ``on_retry(id, why)`` when a cell is run again, or its stored file holds no finished cell."""
        cells = list(cells)
        ids = [c.id for c in cells]
        if len(set(ids)) != len(ids):
            raise ValueError(f"duplicate cell ids: {sorted(i for i, n in Counter(ids).items() if n > 1)}")
        report, todo = Report(), []
        for cell in cells:
            stored = store.load(cell.id) if store else None
            if stored is None:
                todo.append(cell)
                if store and on_retry and (why := store.problem(cell.id)):
                    on_retry(cell.id, f"{store.path(cell.id)} {why}: computed again")
            else:
                report.results[cell.id] = stored
                report.reused.append(cell.id)
        if todo:
            if self._backend is None:
                backends = {"serial": _Serial, "local": _Local, "ray": _Ray}
                self._backend = backends[self.kind](self.workers, self.address)
            _drive(self._backend, todo, self.retries, store, report, on_done, on_retry)
        report.results = {i: report.results[i] for i in ids if i in report.results}
        return report

    def close(self) -> None:
        if self._backend is not None:
            self._backend.close()
            self._backend = None

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def run_cells(
    cells: Iterable[Cell],
    executor: str = "local",
    workers: int | None = None,
    address: str | None = None,
    retries: int = 2,
    store: CellStore | None = None,
    on_done: Callable[[str, Any, Failure | None], None] | None = None,
) -> Report:
    """One :meth:`Executor.run` on a fresh executor (see :class:`Executor` for the arguments)."""
    with Executor(executor, workers, address, retries) as runner:
        return runner.run(cells, store, on_done)


def _drive(backend, todo: list[Cell], retries: int, store, report: Report, on_done, on_retry=None) -> None:
    """Keeps at most ``backend.capacity`` cells in flight (so a crashed process takes only
    running cells with it), stores results as they arrive and retries failures.

    A worker process that dies takes every cell running in its pool with it, and which one
    killed it is unknown. So a cell lost beside others costs no attempt: it becomes a suspect
    and runs again alone, where a second death is its own (and counts)."""
    queue, attempts, in_flight = deque(todo), Counter(), {}
    suspects: set[str] = set()
    shared: set[str] = set()  # cells that ran beside another in this attempt
    while queue or in_flight:
        while queue and len(in_flight) < backend.capacity:
            alone = queue[0].id in suspects or any(c.id in suspects for c in in_flight.values())
            if alone and in_flight:
                break  # a suspect runs alone
            cell = queue.popleft()
            attempts[cell.id] += 1
            if in_flight:
                shared.update([cell.id, *(c.id for c in in_flight.values())])
            else:
                shared.discard(cell.id)
            in_flight[backend.submit(cell)] = cell
            if alone:
                break
        for handle, (status, payload, seconds, platform) in backend.wait_some(list(in_flight)):
            cell = in_flight.pop(handle)
            if status == "ok":
                result = json.loads(payload)
                if store:
                    store.save(cell.id, result, seconds, attempts[cell.id], platform)
                report.results[cell.id], report.seconds[cell.id] = result, seconds
                report.computed.append(cell.id)
                if on_done:
                    on_done(cell.id, result, None)
                continue
            error = (payload.strip().splitlines() or ["unknown error"])[-1]
            if status == "lost" and cell.id in shared and cell.id not in suspects:
                suspects.add(cell.id)
                attempts[cell.id] -= 1  # not necessarily its fault: no attempt counted
                queue.appendleft(cell)
                if on_retry:
                    on_retry(cell.id, f"a worker process died while it ran beside others ({error}); "
                             "running it again alone, no attempt counted")  # fmt: skip
            elif attempts[cell.id] <= retries and not any(word in error for word in PERMANENT):
                queue.append(cell)  # deterministic cells fail again; a lost process may not
                if on_retry:
                    on_retry(
                        cell.id, f"attempt {attempts[cell.id]} of {retries + 1} failed ({error}); retrying"
                    )
            else:
                failure = Failure(cell.id, error, payload, attempts[cell.id])
                report.failures[cell.id] = failure
                if on_done:
                    on_done(cell.id, None, failure)


class _Serial:
    """Runs each cell in this process when it is waited for."""

    capacity = 1

    def __init__(self, workers: int, address: str | None) -> None:
        self.cells: dict[int, Cell] = {}

    def submit(self, cell: Cell) -> int:
        self.cells[id(cell)] = cell
        return id(cell)

    def wait_some(self, handles: list) -> list:
        cell = self.cells.pop(handles[0])
        return [(handles[0], call_cell(cell.fn, cell.args))]

    def close(self) -> None:
        pass


def exit_with_parent(parent: int, every: float = 0.5) -> None:
    """In a worker process: end it (at once, as a kill would) when the process ``parent`` that
    started it has gone. A killed ``nirl-mj compare`` would otherwise leave its workers finishing
    their cells, writing into run directories that a restarted command writes into too."""
    import threading

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(every)
        os._exit(1)  # files are written atomically: at worst a temporary is left, removed on resume

    threading.Thread(target=watch, daemon=True, name="exit-with-parent").start()


class _Local:
    """A pool of ``workers`` spawned processes (each ends when this process ends); rebuilt if a
    process dies."""

    def __init__(self, workers: int, address: str | None) -> None:
        self.capacity = workers
        self.pool: ProcessPoolExecutor | None = None
        self.owner: dict[Future, ProcessPoolExecutor] = {}  # the pool each running future belongs to

    def submit(self, cell: Cell) -> Future:
        for _ in range(2):
            if self.pool is None:
                # A rendering context left in a reference cycle must be freed here, on the thread
                # where it is current: collected later on the pool's manager thread, it cannot be.
                gc.collect()
                spawn = multiprocessing.get_context("spawn")  # no inherited MuJoCo or OpenGL state
                self.pool = ProcessPoolExecutor(self.capacity, mp_context=spawn, initializer=exit_with_parent,
                                                initargs=(os.getpid(),))  # fmt: skip
            try:
                future = self.pool.submit(call_cell, cell.fn, cell.args)
            except BrokenProcessPool:  # a worker died since the last wait: start a fresh pool
                self._discard(self.pool)
                continue
            self.owner[future] = self.pool
            return future
        raise ExecutorError("could not start the local worker processes")

    def wait_some(self, handles: list) -> list:
        done, _ = wait(handles, return_when=FIRST_COMPLETED)
        out = []
        for future in done:
            pool = self.owner.pop(future, None)
            try:
                out.append((future, future.result()))
            except (BrokenProcessPool, CancelledError) as exc:  # a worker died (killed, out of memory)
                out.append((future, ("lost", f"{type(exc).__name__}: a worker process died: {exc}", 0.0, "")))
                self._discard(pool)  # only the broken pool: a replacement started meanwhile stays
        return out

    def _discard(self, pool: ProcessPoolExecutor | None) -> None:
        if pool is not None and pool is self.pool:
            pool.shutdown(wait=False, cancel_futures=True)
            self.pool = None

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None


class _Ray:
    """Ray tasks of one CPU each; starts a local cluster unless given an ``address``."""

    def __init__(self, workers: int, address: str | None) -> None:
        try:
            import ray
        except ImportError:
            raise ExecutorError(RAY_MISSING) from None
        self.ray, self.started, self.scratch = ray, False, None
        if not ray.is_initialized():
            try:
                if address:
                    ray.init(address=address, log_to_driver=False)
                else:
                    self.scratch = ray_scratch()
                    where = {"_temp_dir": self.scratch} if self.scratch else {}
                    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, **where)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                self._remove_scratch()
                raise ExecutorError(
                    f"cannot start or reach Ray (address {address or 'local'}): {exc}"
                ) from None
            self.started = True
        self.capacity = max(1, int(ray.cluster_resources().get("CPU", workers)))
        # Our own retries (the same for every executor), so Ray's are off.
        self.remote = ray.remote(num_cpus=1, max_retries=0)(call_cell)

    def submit(self, cell: Cell):
        return self.remote.remote(cell.fn, cell.args)

    def wait_some(self, handles: list) -> list:
        done, _ = self.ray.wait(handles, num_returns=1)
        out = []
        for ref in done:
            try:
                out.append((ref, self.ray.get(ref)))
            except self.ray.exceptions.RayError as exc:  # a worker or node was lost
                out.append((ref, ("error", f"{type(exc).__name__}: {exc}", 0.0, "")))
        return out

    def close(self) -> None:
        if self.started:
            self.ray.shutdown()
            self._remove_scratch()

    def _remove_scratch(self) -> None:
        if self.scratch:
            shutil.rmtree(self.scratch, ignore_errors=True)
            self.scratch = None


def ray_scratch() -> str | None:
    """A folder of its own for a local Ray cluster's session (sockets, worker logs), removed when the
    executor closes: by default Ray leaves ``/tmp/ray/session_<time>`` behind after every start. None
    where ``RAY_TMPDIR`` is set: the user chose where Ray writes, and Ray keeps what it writes there.
    Ray's root otherwise (``TMPDIR`` on Linux, ``/tmp`` on macOS), so its socket paths stay as short
    as Ray's own (a Unix socket's path holds at most 107 bytes)."""
    if "RAY_TMPDIR" in os.environ:
        return None
    root = "/tmp" if sys.platform == "darwin" else tempfile.gettempdir()
    return tempfile.mkdtemp(prefix="nirl-ray-", dir=root)
