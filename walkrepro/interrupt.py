"""Ctrl-C as a request, checked between steps, so an interrupted run is still a useful run.

The first Ctrl-C sets a flag that the run loop and the stages around it check at safe
points (between physics steps, between set-up stages, before figures): the log is closed
whole, and metrics and the verdict are still written. A second Ctrl-C interrupts at once
(Python's usual ``KeyboardInterrupt``), for when a stage does not reach a safe point soon.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType


class InterruptFlag:
    """Turns the first SIGINT into :attr:`requested` while installed (main thread only).

    Use as a context manager; outside the main thread (a worker thread) it installs nothing
    and the flag stays false.
    """

    def __init__(self) -> None:
        self.requested = False
        self._previous: object = None
        self._installed = False

    def __enter__(self) -> InterruptFlag:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)
            self._installed = True
        return self

    def __exit__(self, *exc: object) -> None:
        if self._installed:
            signal.signal(signal.SIGINT, self._previous)  # type: ignore[arg-type]
            self._installed = False

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True
        # The next Ctrl-C raises KeyboardInterrupt wherever the program is.
        signal.signal(signal.SIGINT, signal.default_int_handler)


@contextmanager
def sigint_raises() -> Iterator[None]:
    """Inside, SIGINT raises ``KeyboardInterrupt`` (main thread only), whatever the process
    inherited.

    A process started with SIGINT ignored (a background job of a non-interactive shell, or
    under ``nohup``) keeps it ignored, Python's default handler included, so Ctrl-C or a
    ``kill -INT`` would not stop it. Commands that stop on ``KeyboardInterrupt`` (the sweep)
    install the handler themselves, as :class:`InterruptFlag` does for a run.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
