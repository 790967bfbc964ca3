"""Sweep engines: they schedule cells and never change what a cell computes.

- :class:`ProcessEngine` (default): ``jobs`` worker processes, started once and reused for
  every cell (imports, robot models and compiled kernels are loaded once per worker). The
  parent knows which cell each worker runs, so a worker that dies (killed, segfault) marks
  exactly that cell ``crashed``, is replaced, and the sweep goes on. Workers sit in their own
  process group: a Ctrl-C at the terminal reaches only the parent, which stops them.
- :class:`RayEngine` (``--engine ray``): the same cells as Ray tasks, on a local Ray started
  for the sweep or an existing cluster (``address``). Optional: ``pip install -e ".[ray]"``.

Both yield :class:`~walkrepro.studies.sweep.cells.CellResult` in the order cells finish. The
process pool also runs ``walkrepro check --jobs``'s experiments (another task function, and
its own result for a dead worker), and can be asked to stop: it then starts no more tasks and
asks the running ones to stop (SIGTERM, which a run takes as a request), and still yields
what they return.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from multiprocessing.connection import Connection, wait
from typing import Protocol

from walkrepro.errors import WalkreproError
from walkrepro.locations import USER_EXPERIMENTS_ENV
from walkrepro.studies.sweep.cells import CRASHED, CellResult, CellTask, run_cell

CellFn = Callable[[CellTask], CellResult]
#: The result of a task whose worker died: ``crashed(task index, message, engine time [s])``.
CrashedFn = Callable[[int, str, float], object]
ENGINES = ("process", "ray")
#: How often a waiting pool looks at its ``stop`` request [s].
STOP_POLL = 0.2


def crashed_cell(index: int, message: str, engine_time: float) -> CellResult:
    """The result of a cell whose worker died."""
    return CellResult(index, CRASHED, message, engine_time=engine_time)


class Engine(Protocol):
    """Runs cells; yields each result as its cell finishes."""

    def run(self, tasks: Sequence[CellTask]) -> Iterator[CellResult]:
        """Run every task once; results in completion order."""
        ...


def make_engine(
    name: str,
    jobs: int,
    address: str | None = None,
    fn: Callable = run_cell,
    crashed: CrashedFn = crashed_cell,
) -> Engine:
    """The engine called ``name`` (``process`` or ``ray``), running ``fn`` on each task
    (a sweep cell's by default) and ``crashed`` for a task whose worker died.

    Raises:
        WalkreproError: unknown engine, ``--address`` without Ray, or Ray not installed.
    """
    if name == "process":
        if address is not None:
            raise WalkreproError("--address applies to --engine ray only.")
        return ProcessEngine(jobs, fn, crashed)
    if name == "ray":
        return RayEngine(jobs, address, fn, crashed)
    raise WalkreproError(f"unknown engine {name!r}. Valid engines: {', '.join(ENGINES)}.")


class ProcessEngine:
    """A pool of ``jobs`` reused worker processes, one task per worker at a time.

    Args:
        jobs: number of worker processes (>= 1).
        fn: the task function, module-level (picklable): a sweep cell's by default (tests
            substitute one that crashes); ``walkrepro check --jobs`` gives its own. A task
            has an ``index``; a result is a dataclass with an ``engine_time`` field.
        crashed: the result of a task whose worker died (:func:`crashed_cell` for cells).
    """

    def __init__(
        self, jobs: int, fn: Callable = run_cell, crashed: CrashedFn = crashed_cell
    ) -> None:
        if jobs < 1:
            raise WalkreproError(f"--jobs {jobs}: need at least one process.")
        self.jobs = jobs
        self.fn = fn
        self.crashed = crashed
        self._started: list[tuple[Connection, mp.process.BaseProcess]] = []

    def start(self, n_tasks: int) -> None:
        """Start the workers now (before a progress bar's thread exists: a fork copies only
        the forking thread, so no other thread may hold a lock the worker needs)."""
        ctx = mp.get_context()
        while len(self._started) < min(self.jobs, n_tasks):
            self._started.append(self._spawn(ctx))

    def run(
        self, tasks: Sequence[CellTask], stop: Callable[[], bool | int | None] | None = None
    ) -> Iterator[CellResult]:
        """Run every task; a dead worker's task is ``crashed`` and the worker is replaced.

        Args:
            tasks: what to run.
            stop: polled while waiting (every :data:`STOP_POLL` s); once it returns true or
                a signal number, no more tasks start, the running ones are sent that signal
                (SIGTERM for true; a run takes SIGINT or SIGTERM as a stop request and
                returns interrupted), and their results are still yielded.
        """
        pending = deque(tasks)
        stopping = False
        busy: dict[Connection, tuple[mp.process.BaseProcess, CellTask, float]] = {}
        idle, self._started = self._started, []
        ctx = mp.get_context()
        try:
            while len(idle) < min(self.jobs, len(pending)):
                idle.append(self._spawn(ctx))
            while pending or busy:
                asked = stop() if stop is not None and not stopping else None
                if asked:
                    stopping = True
                    pending.clear()
                    signum = signal.SIGTERM if asked is True else int(asked)
                    for proc, _, _ in busy.values():
                        os.kill(proc.pid, signum)  # the run's own flag takes it
                while idle and pending:
                    conn, proc = idle.pop()
                    task = pending.popleft()
                    t0 = time.perf_counter()  # before sending: the worker starts during send
                    conn.send(task)
                    busy[conn] = (proc, task, t0)
                ready = wait(list(busy), timeout=None if stop is None else STOP_POLL)
                for conn in ready:
                    assert isinstance(conn, Connection)
                    proc, task, t0 = busy.pop(conn)
                    try:
                        result = conn.recv()
                    except (EOFError, OSError):
                        proc.join(timeout=5)
                        conn.close()
                        yield self.crashed(
                            task.index,
                            f"worker process {proc.pid} died (exit code {proc.exitcode}) "
                            "while running this task",
                            time.perf_counter() - t0,
                        )
                        if pending:
                            idle.append(self._spawn(ctx))
                        continue
                    idle.append((conn, proc))
                    yield replace(result, engine_time=time.perf_counter() - t0)
        finally:
            for conn, proc in [*idle, *((c, p) for c, (p, _, _) in busy.items())]:
                try:
                    conn.send(None)
                except OSError:
                    pass
                if (conn, proc) not in idle:  # still running a cell: stop it now
                    proc.terminate()
            for conn, proc in [*idle, *((c, p) for c, (p, _, _) in busy.items())]:
                proc.join(timeout=10)
                if proc.is_alive():
                    proc.kill()
                    proc.join()
                conn.close()

    def _spawn(self, ctx: mp.context.BaseContext) -> tuple[Connection, mp.process.BaseProcess]:
        """A worker running ``self.fn`` on what the returned connection sends it."""
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=_worker, args=(child, self.fn), daemon=True)
        proc.start()
        child.close()  # only the worker holds its end: its death is EOF here
        return parent, proc


def _worker(conn: Connection, fn: Callable) -> None:
    """Run tasks from ``conn`` until ``None`` or EOF."""
    # Own process group: the terminal's Ctrl-C goes to the parent, which stops the workers.
    os.setpgrp()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # The parent's terminate() between cells ends the worker at once (a handler inherited
    # through fork would hold it); during a cell, the run's own flag takes it as a stop.
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        try:
            conn.send(fn(task))
        except (BrokenPipeError, OSError):
            return


RAY_INSTALL = 'pip install -e ".[ray]"'


def import_ray():  # noqa: ANN201 - the ray module
    """Ray, or a user error with the install command."""
    try:
        import ray
    except ImportError:
        raise WalkreproError(
            f"--engine ray needs Ray, which is not installed. Install it with {RAY_INSTALL} "
            "(from the repository root), or use --engine process."
        ) from None
    return ray


class RayEngine:
    """Cells as Ray tasks (one CPU each, no retries: a crash is recorded, not re-run).

    Args:
        jobs: CPUs of the local Ray started for the sweep (ignored with ``address``).
        address: an existing cluster (``ray://…`` or ``host:port``, or ``auto``).
        fn: the task function (a sweep cell's by default), as for :class:`ProcessEngine`.
        crashed: the result of a task that failed in Ray (:func:`crashed_cell` for cells).
    """

    def __init__(
        self,
        jobs: int,
        address: str | None = None,
        fn: Callable = run_cell,
        crashed: CrashedFn = crashed_cell,
    ) -> None:
        if jobs < 1:
            raise WalkreproError(f"--jobs {jobs}: need at least one process.")
        self.ray = import_ray()
        self.jobs = jobs
        self.address = address
        self.fn = fn
        self.crashed = crashed

    def run(
        self, tasks: Sequence[CellTask], stop: Callable[[], bool | int | None] | None = None
    ) -> Iterator[CellResult]:
        """Submit every task; yield results as they complete.

        Args:
            tasks: what to run.
            stop: polled while waiting (every :data:`STOP_POLL` s); once it returns true,
                the unfinished tasks are cancelled (Ray interrupts a running one) and not
                yielded: a run directory so stopped is kept, marked interrupted, but its
                result does not come back, unlike the process pool's.
        """
        ray = self.ray
        started = not ray.is_initialized()
        if started:
            self._init()
        remote = ray.remote(num_cpus=1, max_retries=0)(self.fn)
        refs = {}
        try:
            for task in tasks:
                refs[remote.remote(task)] = task
            stopping = False
            while refs:
                if stop is not None and not stopping and stop():
                    stopping = True
                    for ref in refs:
                        ray.cancel(ref)
                timeout = None if stop is None or stopping else STOP_POLL
                done, _ = ray.wait(list(refs), num_returns=1, timeout=timeout)
                for ref in done:
                    task = refs.pop(ref)
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.TaskCancelledError:
                        continue  # stopped on request: no result
                    except ray.exceptions.RayError as exc:
                        first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                        result = self.crashed(
                            task.index, f"Ray task failed: {type(exc).__name__}: {first}", math.nan
                        )
                    yield result
        finally:
            for ref in refs:
                ray.cancel(ref, force=True)
            if started:
                ray.shutdown()

    def _init(self) -> None:
        ray = self.ray
        # The workers must import this walkrepro: pass the driver's module path on.
        env = {"PYTHONPATH": os.pathsep.join(p for p in _pythonpath() if p)}
        if os.environ.get(USER_EXPERIMENTS_ENV):  # walkrepro --experiments DIR
            env[USER_EXPERIMENTS_ENV] = os.environ[USER_EXPERIMENTS_ENV]
        kwargs: dict = {
            "runtime_env": {"env_vars": env},
            "include_dashboard": False,
            "log_to_driver": False,
            "configure_logging": False,
        }
        try:
            if self.address is None:
                ray.init(num_cpus=self.jobs, **kwargs)
            else:
                ray.init(address=self.address, **kwargs)
        except Exception as exc:  # noqa: BLE001 - Ray raises many kinds for a bad address
            where = f"the Ray cluster at {self.address}" if self.address else "a local Ray"
            raise WalkreproError(f"could not start or reach {where}: {exc}") from None


def _pythonpath() -> list[str]:
    """The directory holding this ``walkrepro`` package, plus any PYTHONPATH already set."""
    from pathlib import Path

    here = str(Path(__file__).resolve().parents[3])
    return [here, *os.environ.get("PYTHONPATH", "").split(os.pathsep)]
