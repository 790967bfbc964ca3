"""Ctrl-C and SIGTERM as a request, checked between steps, so a stopped run is still useful.

The first Ctrl-C (SIGINT) or SIGTERM (what batch schedulers, containers and Ray send before
they kill) sets a flag that the run loop and the stages around it check at safe points
(between physics steps, between set-up stages, before figures): the log is closed whole,
and metrics and the verdict are still written. A second signal of either kind interrupts at
once (Python's usual ``KeyboardInterrupt``), for when a stage does not reach a safe point
soon. A command stopped this way exits with ``128 + signal number``: 130 after Ctrl-C, 143
after SIGTERM, as a shell reports a process killed by that signal.

Before any of that is installed, the process spends 0.6-1.5 s importing MuJoCo and numba.
:func:`hold_stop_signals_if_command`, called by the command's set-up
(:func:`walkrepro.cli.command_setup`) before those imports, holds a stop signal of that
time: the first :class:`InterruptFlag` or :func:`stop_signals_raise` takes it over as if it
had just come, and one that nothing takes over is delivered when the process exits, so a
stop is never lost. Importing walkrepro installs nothing: a program that uses the library
keeps its own handlers, except while a run is under way (its :class:`InterruptFlag`).
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from types import FrameType

#: The signals that ask walkrepro to stop: Ctrl-C, and the polite kill of schedulers.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def exit_code(signum: int | None) -> int:
    """The exit code of a command stopped by ``signum`` (130 when it is not known)."""
    return 128 + int(signum if signum is not None else signal.SIGINT)


class InterruptFlag:
    """Turns the first SIGINT or SIGTERM into :attr:`requested` while installed (main
    thread only); the second raises ``KeyboardInterrupt``.

    Use as a context manager; outside the main thread (a worker thread) it installs nothing
    and the flag stays false.

    Attributes:
        requested: a stop was asked for.
        signum: the first signal received (None before any).
    """

    def __init__(self) -> None:
        self.requested = False
        self.signum: int | None = None
        self._previous: dict[int, object] = {}

    @property
    def exit_code(self) -> int:
        """``128 + signum`` of the first signal: 130 for Ctrl-C, 143 for SIGTERM."""
        return exit_code(self.signum)

    def __enter__(self) -> InterruptFlag:
        if threading.current_thread() is threading.main_thread():
            held = _take_over_held()
            for signum in STOP_SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
            if held is not None:  # came during start-up: a request, as if it came now
                self.requested, self.signum = True, held
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)  # type: ignore[arg-type]
        self._previous = {}

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.requested:  # the second signal: stop wherever the program is
            raise KeyboardInterrupt
        self.requested = True
        self.signum = signum


@dataclass
class Received:
    """The stop signal that a :func:`stop_signals_raise` block received (None if none)."""

    signum: int | None = None

    @property
    def exit_code(self) -> int:
        """``128 + signum``: 130 for Ctrl-C, 143 for SIGTERM."""
        return exit_code(self.signum)


@contextmanager
def stop_signals_raise(received: Received | None = None) -> Iterator[Received]:
    """Inside, SIGINT and SIGTERM raise ``KeyboardInterrupt`` (main thread only), whatever
    the process inherited; the signal is recorded in the yielded :class:`Received` (the one
    given, if any: a signal held since start-up raises at once, before the block's body).

    A process started with SIGINT ignored (a background job of a non-interactive shell, or
    under ``nohup``) keeps it ignored, Python's default handler included, so Ctrl-C or a
    ``kill -INT`` would not stop it; SIGTERM's default kills at once, with no clean-up.
    Commands that stop on ``KeyboardInterrupt`` (the sweep) install this themselves, as
    :class:`InterruptFlag` does for a run.
    """
    received = received if received is not None else Received()
    if threading.current_thread() is not threading.main_thread():
        yield received
        return
    held = _take_over_held()

    def handle(signum: int, frame: FrameType | None) -> None:
        if received.signum is None:
            received.signum = signum
        raise KeyboardInterrupt

    previous = {signum: signal.signal(signum, handle) for signum in STOP_SIGNALS}
    try:
        if held is not None:
            received.signum = held
            raise KeyboardInterrupt
        yield received
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@dataclass
class _Held:
    """The start-up hold: whether it is on, the handlers it replaced, the signal it holds."""

    on: bool = False
    original: dict[int, object] | None = None
    signum: int | None = None


_HELD = _Held()


def started_as_command(argv: list[str] | None = None, orig_argv: list[str] | None = None) -> bool:
    """Whether this process is the ``walkrepro`` command (its console script, or
    ``python -m walkrepro``), not a program that imports walkrepro."""
    argv = sys.argv if argv is None else argv
    orig_argv = getattr(sys, "orig_argv", []) if orig_argv is None else orig_argv
    script = os.path.basename(argv[0]) if argv else ""
    return script in ("walkrepro", "walkrepro.exe") or orig_argv[1:3] == ["-m", "walkrepro"]


def hold_stop_signals_if_command() -> bool:
    """When this process is the ``walkrepro`` command, hold SIGINT and SIGTERM from now on
    (main thread only); returns whether it did.

    Meant to run first in the command's set-up, before the slow imports: the first
    stop signal is held (a second raises ``KeyboardInterrupt``, as usual), the first
    :class:`InterruptFlag` or :func:`stop_signals_raise` takes it over and puts the
    original handlers back, and a signal still held when the process exits is delivered
    then with its default action, so the command still ends by it. A program that imports
    walkrepro is left alone.
    """
    if _HELD.on or not started_as_command():
        return False
    if threading.current_thread() is not threading.main_thread():
        return False
    _HELD.original = {signum: signal.signal(signum, _hold) for signum in STOP_SIGNALS}
    _HELD.on, _HELD.signum = True, None
    atexit.register(_deliver_unclaimed)
    if hasattr(os, "register_at_fork"):  # a forked worker is not the command: no hold
        os.register_at_fork(after_in_child=_forget_hold)
    return True


def _hold(signum: int, frame: FrameType | None) -> None:
    # The second signal, or one in a forked child (whose hold is off): stop at once.
    if _HELD.signum is not None or not _HELD.on:
        raise KeyboardInterrupt
    _HELD.signum = signum


def _forget_hold() -> None:
    """In a forked child: the parent's hold and held signal are not the child's."""
    _HELD.on, _HELD.original, _HELD.signum = False, None, None


def _take_over_held() -> int | None:
    """End the start-up hold (original handlers back); returns the signal it held, if any."""
    if not _HELD.on:
        return None
    for signum, handler in (_HELD.original or {}).items():
        signal.signal(signum, handler)  # type: ignore[arg-type]
    _HELD.on, _HELD.original = False, None
    held, _HELD.signum = _HELD.signum, None
    return held


def _deliver_unclaimed() -> None:
    """At exit: a signal held since start-up that nothing took over ends the process now."""
    held = _take_over_held()
    if held is not None:
        signal.signal(held, signal.SIG_DFL)
        os.kill(os.getpid(), held)
