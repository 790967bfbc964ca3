"""The paper's claims as the report shows them: one per verdict row.

A row of ``check.json`` (see :meth:`walkrepro.evaluation.checks.Verdict.to_json`) holds the paper's
value, the measured value, the status and a note that ends, for a known deviation, with
``Known deviation: <reason>``; this module splits the note back into the metric's
definition and the reason, and counts statuses the way the index shows them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from walkrepro.evaluation.checks import STATUS_WORDS

#: ``check.json`` statuses and the words the report uses for them: the CLI's
#: (:data:`walkrepro.evaluation.checks.STATUS_WORDS`).
STATUS_LABELS: Mapping[str, str] = STATUS_WORDS
_REASON_MARK = "Known deviation: "


@dataclass(frozen=True)
class Claim:
    """One of the paper's claims and how the reproduction measures against it.

    Attributes:
        metric: the metric (with its argument), or a map claim's label.
        source: where in the paper the claim comes from (section, figure, quote).
        paper: the paper's value or band as text, e.g. ``[0.088, 0.132]`` or ``== 0``.
        measured: the measured value as text (``not measurable`` for a missing value).
        observed: a known deviation's observed band as text (``""`` otherwise).
        status: one of :data:`STATUS_LABELS`' keys.
        definition: how the metric is measured (the spec's note), may be empty.
        reason: why the reproduction misses the paper (known deviation) or why the row
            fails; empty for a reproduced claim.
    """

    metric: str
    source: str
    paper: str
    measured: str
    observed: str
    status: str
    definition: str
    reason: str

    @property
    def label(self) -> str:
        """The verdict in words (``reproduced``, ``known deviation``...)."""
        return STATUS_LABELS.get(self.status, self.status)


def format_value(value: float | None) -> str:
    """A measured value with four significant digits; None or NaN is ``not measurable``."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "not measurable"
    return f"{value:.4g}"


def _band(observed: object) -> str:
    if observed is None:
        return ""
    if isinstance(observed, str):
        return observed
    lo, hi = observed  # type: ignore[misc]
    return f"[{lo:g}, {hi:g}]"


def claim_from_row(row: Mapping[str, object]) -> Claim:
    """A :class:`Claim` from one ``check.json`` row."""
    note = str(row.get("note") or "")
    status = str(row.get("status", "fail"))
    definition, reason = note, ""
    if _REASON_MARK in note:
        definition, reason = note.split(_REASON_MARK, 1)
        if status != "known deviation":  # a deviation that left its band: keep the whole note
            reason = note
    elif status == "fail":
        definition, reason = "", note
    paper = row.get("band")
    if paper is None:
        value = row.get("paper")
        paper = f"{row.get('op', '')} {value}"
    return Claim(
        metric=str(row.get("metric", "")),
        source=str(row.get("source", "")),
        paper=str(paper),
        measured=format_value(row.get("measured")),  # type: ignore[arg-type]
        observed=_band(row.get("observed")),
        status=status,
        definition=definition.strip(),
        reason=reason.strip(),
    )


def experiment_claims(check: Mapping[str, object]) -> list[Claim]:
    """The claims of one experiment's ``check.json``, plus a failed row for a run that did
    not end ``complete`` or ``fell`` (as :func:`walkrepro.evaluation.checks.count` counts it)."""
    claims = [claim_from_row(r) for r in check.get("rows", [])]  # type: ignore[union-attr]
    outcome = str(check.get("outcome", ""))
    if outcome not in ("complete", "fell"):
        claims.insert(0, Claim("run", "", "complete", outcome, "", "fail", "", f"run {outcome}"))
    return claims


@dataclass(frozen=True)
class Tally:
    """Claims by verdict."""

    reproduced: int = 0
    calibrated: int = 0
    known: int = 0
    failed: int = 0

    def __add__(self, other: Tally) -> Tally:
        return Tally(
            self.reproduced + other.reproduced,
            self.calibrated + other.calibrated,
            self.known + other.known,
            self.failed + other.failed,
        )


def tally(claims: Iterable[Claim]) -> Tally:
    """Count claims by status (an unknown status counts as failed)."""
    statuses = [c.status for c in claims]
    known = ("pass", "calibrated", "known deviation")
    return Tally(
        reproduced=statuses.count("pass"),
        calibrated=statuses.count("calibrated"),
        known=statuses.count("known deviation"),
        failed=sum(s not in known for s in statuses),
    )
