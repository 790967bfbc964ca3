"""User-facing errors.

Every error a user can cause (bad spec, unknown name, unwritable directory) is a
``WalkreproError``. The CLI prints its message as one paragraph and exits with code 2,
without a traceback; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

from collections.abc import Iterable


class WalkreproError(Exception):
    """An error caused by the user's input, with a message that says how to fix it."""

    exit_code = 2


class SpecError(WalkreproError):
    """A malformed or inconsistent experiment spec."""


class UnknownNameError(WalkreproError):
    """A name (robot, body, controller, metric, experiment, ...) that does not exist."""

    def __init__(self, kind: str, name: str, valid: Iterable[str], where: str = "") -> None:
        valid = sorted(valid)
        prefix = f"{where}: " if where else ""
        super().__init__(
            f"{prefix}unknown {kind} {name!r}. Valid {_plural(kind)}: "
            f"{', '.join(valid) or '(none)'}."
        )
        self.kind = kind
        self.name = name
        self.valid = valid


def _plural(noun: str) -> str:
    """``body`` → ``bodies``, ``robot`` → ``robots``: the kinds of names walkrepro has."""
    return noun[:-1] + "ies" if noun.endswith("y") and noun[-2:-1] not in "aeiou" else noun + "s"
