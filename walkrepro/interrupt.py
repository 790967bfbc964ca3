"""Ctrl-C and SIGTERM as a request, checked between steps, so a stopped run is still useful.

The first Ctrl-C (SIGINT) or SIGTERM (what batch schedulers, containers and Ray send before
they kill) sets a flag that the run loop and the stages around it check at safe points
(between physics steps, between set-up stages, before figures): the log is closed whole,
and metrics and the verdict are still written. A second signal of either kind interrupts at
once (Python's usual ``KeyboardInterrupt``), for when a stage does not reach a safe point
soon. A command stopped this way exits with ``128 + signal number``: 130 after Ctrl-C, 143
after SIGTERM, as a shell reports a process killed by that signal.
"""

from __future__ import annotations

import signal
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
            for signum in STOP_SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
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
def stop_signals_raise() -> Iterator[Received]:
    """Inside, SIGINT and SIGTERM raise ``KeyboardInterrupt`` (main thread only), whatever
    the process inherited; the signal is recorded in the yielded :class:`Received`.

    A process started with SIGINT ignored (a background job of a non-interactive shell, or
    under ``nohup``) keeps it ignored, Python's default handler included, so Ctrl-C or a
    ``kill -INT`` would not stop it; SIGTERM's default kills at once, with no clean-up.
    Commands that stop on ``KeyboardInterrupt`` (the sweep) install this themselves, as
    :class:`InterruptFlag` does for a run.
    """
    received = Received()
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def handle(signum: int, frame: FrameType | None) -> None:
        if received.signum is None:
            received.signum = signum
        raise KeyboardInterrupt

    previous = {signum: signal.signal(signum, handle) for signum in STOP_SIGNALS}
    try:
        yield received
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@contextmanager
def sigint_raises() -> Iterator[None]:
    """Inside, SIGINT and SIGTERM raise ``KeyboardInterrupt`` (see
    :func:`stop_signals_raise`, which also says which signal came)."""
    with stop_signals_raise():
        yield
