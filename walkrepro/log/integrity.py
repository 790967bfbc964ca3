"""One notion of a damaged log, for every reader: ``check --run``, ``export``, ``render``,
``plot``, :func:`walkrepro.evaluate`, ``verify``.

A log is *whole* when its MCAP file reads to its footer with every record intact
(:attr:`walkrepro.log.record.Log.damage` is empty). A log cut short (a killed writer, a copy
that stopped, a full disk) or corrupted is named as such, with how much of the run it holds
and what is missing: ``log cut: holds 1.54 s of 16.5 s; missing its summary and footer (it
ends at byte 5000000; whole records up to byte 4998312)``. The expected length is the run's
own record (``run.json``'s ``sim_time`` beside a run directory's ``log.mcap``), else the
spec's ``sim.duration`` (the log's ``spec.yaml`` attachment).

Readers call :func:`read_checked_log`: a damaged log is a :class:`DamagedLogError` (exit code
1), unless the user asked to use what is there (``--partial``); every output made from it
then says ``partial`` (:data:`PARTIAL`) in its title and verdict.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import yaml

from walkrepro.errors import WalkreproError
from walkrepro.log import record

#: The outcome of a verdict, and the word in every title, made from a damaged log.
PARTIAL = "partial"


class DamagedLogError(WalkreproError):
    """A log that is cut or corrupt, read without ``--partial``."""

    exit_code = 1


@dataclass(frozen=True)
class LogIntegrity:
    """Whether a log is whole, and if not, what it holds and lacks.

    Attributes:
        path: the log file.
        damage: :attr:`walkrepro.log.record.Log.damage` (``""`` when whole).
        held: simulated time of the last state it holds [s] (NaN without states).
        expected: simulated time the run covered (``run.json``), or the spec's duration
            [s] (NaN when neither is known).
        expected_from: where ``expected`` comes from (``run.json`` or ``the spec``).
    """

    path: Path
    damage: str
    held: float
    expected: float
    expected_from: str

    @property
    def whole(self) -> bool:
        """The log reads to its footer with every record intact."""
        return not self.damage

    @property
    def cut(self) -> bool:
        """The file ends before its summary and footer (rather than a damaged record)."""
        return self.damage.startswith("truncated")

    def describe(self) -> str:
        """One sentence: ``log cut: holds 1.54 s of 16.5 s; missing ...`` (``""`` when whole)."""
        if self.whole:
            return ""
        kind = "log cut" if self.cut else "log damaged"
        held = "no state" if math.isnan(self.held) else f"{self.held:.3g} s"
        of = (
            "" if math.isnan(self.expected) else f" of {self.expected:.3g} s ({self.expected_from})"
        )
        if self.cut:
            what = self.damage.removeprefix("truncated: it ends")
            missing = f"missing its summary and footer (it ends{what.split(' without')[0]}"
            rest = what.split("(", 1)[1] if "(" in what else ")"
            missing += f"; {rest}" if rest != ")" else ")"
        else:
            missing = self.damage.removeprefix("damaged").lstrip(": ")
        return f"{kind}: holds {held}{of}; {missing}"

    def short(self) -> str:
        """A title's few words: ``PARTIAL: log cut, holds 1.54 s of 16.5 s`` (``""`` when
        whole)."""
        if self.whole:
            return ""
        held = "no state" if math.isnan(self.held) else f"{self.held:.3g} s"
        of = "" if math.isnan(self.expected) else f" of {self.expected:.3g} s"
        return f"PARTIAL: {'log cut' if self.cut else 'log damaged'}, holds {held}{of}"


def integrity(log: record.Log) -> LogIntegrity:
    """How whole ``log`` is (see :class:`LogIntegrity`)."""
    states = log.arrays(record.TOPIC_STATE, ("t",)).get("t")
    held = float(states[-1]) if states is not None and len(states) else math.nan
    expected, source = math.nan, ""
    run_file = log.path.parent / "run.json"
    if log.path.name == "log.mcap" and run_file.is_file():
        try:
            sim_time = json.loads(run_file.read_text()).get("sim_time")
            if isinstance(sim_time, int | float) and sim_time > 0:
                expected, source = float(sim_time), "run.json"
        except (OSError, ValueError, AttributeError):
            pass
    if math.isnan(expected):
        try:  # the spec's sim.duration, read as plain YAML (the log knows no spec model)
            duration = yaml.safe_load(log.spec_yaml)["sim"]["duration"]
            expected, source = float(duration), "the spec's duration"
        except (yaml.YAMLError, KeyError, TypeError, ValueError):
            pass
    return LogIntegrity(log.path, log.damage, held, expected, source)


def check(log: record.Log, partial: bool = False) -> LogIntegrity:
    """``log``'s integrity; raises unless it is whole or ``partial`` is asked for.

    Raises:
        DamagedLogError: the log is cut or damaged and ``partial`` is false; the message
            says what it holds, what is missing and how to go on.
    """
    found = integrity(log)
    if not found.whole and not partial:
        raise DamagedLogError(
            f"{log.path}: {found.describe()}. Nothing is measured, drawn or exported from a "
            "damaged log as if it were whole; pass --partial to use what it holds (every "
            "output then says partial), or `walkrepro verify` to see where it breaks."
        )
    return found


def read_checked_log(path: Path, partial: bool = False) -> tuple[record.Log, LogIntegrity]:
    """Read a log (:func:`walkrepro.log.record.read_log`) and :func:`check` it.

    Raises:
        WalkreproError: not a readable walkrepro log.
        DamagedLogError: as :func:`check`.
    """
    log = record.read_log(Path(path))
    return log, check(log, partial)


def partial_title(found: LogIntegrity) -> str:
    """The words an output made from a damaged log adds to its title (``""`` when whole)."""
    return "" if found.whole else f"PARTIAL ({found.describe()})"
