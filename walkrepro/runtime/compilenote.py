"""The first run says what it does: numba compiling a controller's kernels on a cold cache.

numba compiles walkrepro's kernels once per machine and source version and keeps them in
its cache (:mod:`walkrepro.runtime.numbacache`); Paper I's controller takes minutes. Before
that, ``walkrepro run`` prints one line (:func:`note`) as soon as the spec is read, before
the imports that compile, and then a spinner with the elapsed time and the count of
functions numba has compiled so far, from numba's own compile events (``numba:compile``,
:mod:`numba.core.event`): numba reports no finer progress within a function.

The cache is cold (:func:`is_cold`) when numba's cache directory holds no index (``.nbi``)
of any kernel module of the controller's package, or, for a controller without kernels of
its own (Paper II's, the posture controller), of the simulator's shared kernels. numba names
an index ``<module>.<function>-<line>.py<version>.nbi`` in a folder
``<source folder name>_<hash of its path>`` of the cache directory.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from walkrepro.runtime.numbacache import PACKAGES

if TYPE_CHECKING:
    from rich.console import Console
    from rich.status import Status

#: Cold compile time [s] of each controller's kernels (with the simulator's), measured on
#: an empty numba cache: ``NUMBA_CACHE_DIR=<empty dir> walkrepro run <experiment> --set
#: sim.duration=0.05 --no-figures`` minus the same warm, on a 2-core machine shared with
#: other work (README.md, "First run"). Only the note's "~N min" uses it.
COMPILE_SECONDS: dict[str, float] = {
    "efsm": 120.0,  # forward_walk: compile 80-129 s (81-162 s cold, 3.6-11 s warm)
    "qpimpedance": 50.0,  # walk_flat_kist: 52 s cold, 3.6 s warm
    "timeprojection": 7.0,  # in_place: 9.8 s cold, 3.3 s warm (the simulator's kernels)
    "posture": 7.0,  # the simulator's kernels and one 6 x 6 solve
}
#: Package whose modules hold the simulator's kernels (every run compiles some of them).
SHARED_KERNELS = "walkrepro.sim"


def _module_file(module: str) -> Path | None:
    """The source file of ``module`` without importing it (its parent packages are)."""
    from importlib.util import find_spec

    try:
        spec = find_spec(module)
    except (ImportError, ValueError):
        return None
    return Path(spec.origin) if spec is not None and spec.origin else None


def _imports_numba(file: Path) -> bool:
    """Whether ``file`` imports numba (so may define kernels), read without importing it."""
    import ast

    try:
        source = file.read_bytes()
    except OSError:
        return False
    if b"numba" not in source:
        return False
    for node in ast.walk(ast.parse(source, str(file))):
        if isinstance(node, ast.Import) and any(a.name.startswith("numba") for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("numba"):
            return True
    return False


def kernel_files(target: str) -> list[Path]:
    """The kernel modules (files that import numba) of the package of a controller's class
    ``target`` (``"module:Class"``, as the plugin registry gives it), or, if it has none, of
    :data:`SHARED_KERNELS`; empty for a module that cannot be found."""
    module = target.partition(":")[0]
    file = _module_file(module)
    if file is None:
        return []
    own = sorted(f for f in file.parent.glob("*.py") if _imports_numba(f))
    if own:
        return own
    shared = _module_file(f"{SHARED_KERNELS}.__init__") or _module_file(SHARED_KERNELS)
    return sorted(f for f in shared.parent.glob("*.py") if _imports_numba(f)) if shared else []


def cache_dir() -> Path | None:
    """numba's cache directory as walkrepro set it (``NUMBA_CACHE_DIR``), or None."""
    import os

    from walkrepro.runtime.numbacache import CACHE_DIR_ENV

    value = os.environ.get(CACHE_DIR_ENV)
    return Path(value) if value else None


def is_cold(target: str, directory: Path | None = None) -> bool:
    """Whether numba's cache holds none of the compiled kernels of the controller class
    ``target`` (``"module:Class"``; see the module's docstring); False if there is no cache
    directory or no kernel to look for."""
    directory = directory or cache_dir()
    files = kernel_files(target)
    if directory is None or not files:
        return False
    for file in files:
        if any(directory.glob(f"{file.parent.name}_*/{file.stem}.*.nbi")):
            return False
    return True


def _duration(seconds: float) -> str:
    """``~2 min`` or ``~40 s``."""
    if seconds >= 90:
        return f"~{int(seconds / 60 + 0.5)} min"  # half up: 150 s is ~3 min
    return f"~{max(10, round(seconds, -1)):.0f} s"


def note(controller: str, paper_label: str | None) -> str:
    """The one line said before compiling, e.g. "compiling the Paper I controller (efsm),
    once per machine: ~2 min"."""
    who = (
        f"the {paper_label} controller ({controller})"
        if paper_label
        else f"the {controller} controller"
    )
    estimate = COMPILE_SECONDS.get(controller)
    when = f": {_duration(estimate)}" if estimate else ""
    return f"compiling {who}, once per machine{when}"


class CompileWatch:
    """Shows numba's compiling while it lasts: the note, then a spinner line with the
    elapsed time and the functions compiled so far, handed over to a progress bar's text
    (:meth:`hand_over`) once one is shown, and silent from the first simulated tick
    (:meth:`finish`, which returns the summary line for the bar's console to print).

    Args:
        console: where to print (the terminal's stderr).
        message: the note to print now (the cache is cold), or None: then the note is
            printed only if numba does compile (``fallback``).
        fallback: the note for a compile the cold check did not foresee.
    """

    #: Least time between two display updates [s].
    REFRESH = 0.25

    def __init__(self, console: Console, message: str | None, fallback: str) -> None:
        self._console, self._message, self._fallback = console, message, fallback
        self._start = time.monotonic()
        self._count = 0
        self._current = ""
        self._shown = 0.0
        self._status: Status | None = None
        self._update: Callable[[str], None] | None = None
        self._listener: Any = None
        self._done = False

    def __enter__(self) -> CompileWatch:
        if self._message is not None:
            self._say(self._message)
        from numba.core import event

        watch = self

        class _Listener(event.Listener):
            def on_start(self, ev: Any) -> None:
                watch._compiling(ev.data.get("dispatcher"))

            def on_end(self, ev: Any) -> None:
                pass

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc: object) -> None:
        summary = self.finish()
        if summary is not None and self._update is None:
            self._console.print(summary, highlight=False)

    def _say(self, message: str) -> None:
        """Print the note and start the spinner (once)."""
        self._message = message
        self._console.print(f"[bold]{message}[/]", highlight=False)
        if self._update is None and self._status is None:
            self._status = self._console.status(self._text())
            self._status.start()

    def _text(self) -> str:
        """The spinner's line; in a progress bar (narrower) without the function's name."""
        elapsed = time.monotonic() - self._start
        minutes, seconds = divmod(int(elapsed), 60)
        done = f"{self._count} function{'s' if self._count != 1 else ''}"
        if self._update is not None:
            return f"compiling {minutes}:{seconds:02d}, {done}"
        current = f", now {self._current}" if self._current else ""
        return f"compiling {minutes}:{seconds:02d}, {done} compiled{current}"

    def _compiling(self, dispatcher: Any) -> None:
        """numba starts compiling a function (a kernel or a callee it inlines)."""
        if self._done:
            return
        if self._message is None:
            self._say(self._fallback)
        self._count += 1
        func = getattr(dispatcher, "py_func", None)
        module = getattr(func, "__module__", "") or ""
        if module.partition(".")[0] in PACKAGES:  # not numba's own overloads
            self._current = f"{module.rpartition('.')[2]}.{func.__qualname__}"
        now = time.monotonic()
        if now - self._shown >= self.REFRESH:
            self._shown = now
            self._show(self._text())

    def _show(self, text: str) -> None:
        if self._update is not None:
            self._update(text)
        elif self._status is not None:
            self._status.update(text)

    @property
    def compiling(self) -> bool:
        """Whether the note was printed (the cache was cold, or numba compiled)."""
        return self._message is not None

    def hand_over(self, update: Callable[[str], None]) -> None:
        """Show the compile's progress through ``update`` (a progress bar's text) from now
        on, stopping the spinner (rich shows one live display at a time)."""
        if self._status is not None:
            self._status.stop()
            self._status = None
        self._update = update
        if self.compiling and not self._done:
            update(self._text())

    def finish(self) -> str | None:
        """Stop listening and showing (the run's first tick, or the end). Returns what was
        compiled and how long it took, for the caller to print, or None if nothing was."""
        if self._done:
            return None
        self._done = True
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
        if self._status is not None:
            self._status.stop()
            self._status = None
        if not self.compiling:
            return None
        elapsed = time.monotonic() - self._start
        return (
            f"compiled {self._count} function{'s' if self._count != 1 else ''} in "
            f"{elapsed:.0f} s; later runs load them from numba's cache"
        )
