"""The paper's expectations evaluated against a run's metrics: a verdict table.

An expectation passes (``reproduced``) when ``measured op value`` holds. A missing
measurement (NaN, or a metric that is not measurable, with its reason) fails.

An expectation marked ``calibrated: <parameter>`` is a claim the reproduction used as the
criterion of a declared calibration (``experiments/calibration/<paper>.yaml``; see
docs/calibration.md). It is evaluated like any row, and when it holds its status is
``calibrated``, counted apart from ``reproduced``: the model was tuned to meet it, so meeting
it is no prediction.

An expectation marked ``known_deviation`` carries the band the reproduction measures today
(``observed``). Its row is a ``known deviation`` while the measurement stays inside that
band, and fails when it leaves it in either direction: worse is a regression, better means
the deviation may be gone and the spec must be updated. A NaN never stays in a band.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from walkrepro.specs.deviation import NOT_MEASURABLE
from walkrepro.specs.models import Expectation, ExperimentSpec

PASS, FAIL, KNOWN = "pass", "fail", "known deviation"
#: A row that holds and whose claim served as a calibration criterion (not a prediction).
CALIBRATED = "calibrated"


@dataclass(frozen=True)
class CheckRow:
    """One evaluated expectation.

    Attributes:
        metric: metric name (with argument).
        op: comparison operator.
        paper: the expected value or band, as written in the spec.
        measured: the run's value (NaN if unavailable).
        status: ``pass``, ``calibrated``, ``fail`` or ``known deviation``.
        source: where in the paper the expectation comes from.
        note: free text from the spec, plus the deviation reason (and, when a known
            deviation left its band, which way), or why the metric is not measurable.
        observed: a known deviation's observed band ``(low, high)`` or ``"not measurable"``,
            else None.
        claim: the id of the paper claim the row tests (its register:
            ``experiments/claims/<paper>.yaml``), or None.
        own: the kind of walkrepro's own claim the row is (``generalisation``,
            ``sensitivity``, ``ablation``, ``sanity``), or None.
    """

    metric: str
    op: str
    paper: float | tuple[float, float]
    measured: float
    status: str
    source: str
    note: str
    observed: tuple[float, float] | str | None = None
    claim: str | None = None
    own: str | None = None

    @property
    def word(self) -> str:
        """The status as every output says it: ``reproduced``, ``calibrated``, ``known
        deviation`` or ``failed`` (:data:`STATUS_WORDS`; ``status`` keeps the stored
        ``check.json`` value)."""
        return STATUS_WORDS.get(self.status, self.status)

    @property
    def measured_text(self) -> str:
        """The measured value as text (4 significant digits), or ``not measurable``."""
        return NOT_MEASURABLE if math.isnan(self.measured) else f"{self.measured:.4g}"

    @property
    def band(self) -> str:
        """The expectation as text, e.g. ``between 0.07 and 0.16``."""
        if self.op == "between":
            lo, hi = self.paper  # type: ignore[misc]
            return f"[{lo:g}, {hi:g}]"
        return f"{self.op} {self.paper:g}"

    @property
    def observed_band(self) -> str:
        """A known deviation's observed band as text, ``""`` for other rows."""
        if self.observed is None or isinstance(self.observed, str):
            return self.observed or ""
        return f"[{self.observed[0]:g}, {self.observed[1]:g}]"


@dataclass(frozen=True)
class Counts:
    """Rows by status over one or more verdicts (a bad run outcome counts as a failed row).

    Attributes:
        reproduced: rows that hold (predictions met).
        calibrated: rows that hold and served as a calibration criterion.
        known: known deviations inside their observed band.
        failed: failing rows, plus runs that did not end ``complete`` or ``fell``.
    """

    reproduced: int
    calibrated: int
    known: int
    failed: int

    @property
    def total(self) -> int:
        """Every row (and every broken run), as the JUnit report counts test cases."""
        return self.reproduced + self.calibrated + self.known + self.failed

    def __str__(self) -> str:
        known = "known deviation" if self.known == 1 else "known deviations"
        return (
            f"{self.reproduced} reproduced, {self.calibrated} calibrated, {self.known} {known}, "
            f"{self.failed} failed"
        )


def count(verdicts: list[Verdict]) -> Counts:
    """Count the rows of ``verdicts`` (and each run that did not end ``complete`` or ``fell``)."""
    rows = [r for v in verdicts for r in v.rows]
    return Counts(
        reproduced=sum(r.status == PASS for r in rows),
        calibrated=sum(r.status == CALIBRATED for r in rows),
        known=sum(r.status == KNOWN for r in rows),
        failed=sum(r.status == FAIL for r in rows) + sum(not v.run_ok for v in verdicts),
    )


@dataclass(frozen=True)
class Verdict:
    """All rows of one run, and the outcome of the run itself."""

    experiment: str
    outcome: str
    rows: tuple[CheckRow, ...]

    @property
    def run_ok(self) -> bool:
        """The run ended as a run can (``complete`` or ``fell``), not interrupted or broken."""
        return self.outcome in ("complete", "fell")

    @property
    def passed(self) -> bool:
        """No failing row, and the run was not interrupted or broken."""
        return self.run_ok and all(r.status != FAIL for r in self.rows)

    def __str__(self) -> str:
        """The verdict as ``walkrepro run`` prints it: the experiment's line, then one line
        per row, in the CLI's words (:data:`STATUS_WORDS`)."""
        return "\n".join([summary_line(self), *claim_lines(self)])

    def to_json(self) -> dict:
        """Plain data for ``check.json``."""
        return {
            "experiment": self.experiment,
            "outcome": self.outcome,
            "passed": self.passed,
            "rows": [
                {
                    **asdict(r),
                    "measured": None if math.isnan(r.measured) else r.measured,
                    "band": r.band,
                }
                for r in self.rows
            ],
            "counts": asdict(count([self])),
        }


def summary_line(verdict: Verdict, name_width: int = 0) -> str:
    """One line for one experiment (or map): verdict, name, run outcome and row counts.

    E.g. ``FAIL  human_push   fell    3 reproduced, 0 calibrated, 2 known deviations, 1 failed``.
    The counts keep :class:`Counts`' wording, so the batch summary line that follows parses
    the same way.

    Args:
        verdict: the experiment's verdict.
        name_width: pad the name to this many characters, to align a batch's lines.
    """
    mark = "ok  " if verdict.passed else "FAIL"
    return f"{mark}  {verdict.experiment:<{name_width}}  {verdict.outcome:<11} {count([verdict])}"


#: How every output names each status (the words of the count line): the CLI, the Python
#: API (:attr:`CheckRow.word`), the report and the Rerun recording's verdict panel. A row
#: whose metric gave no value shows ``not measurable`` as its measured value.
STATUS_WORDS = {
    PASS: "reproduced",
    CALIBRATED: "calibrated",
    KNOWN: "known deviation",
    FAIL: "failed",
}


def claim_lines(verdict: Verdict) -> list[str]:
    """One line per row of ``verdict``: status, claim (the metric), the paper's value, the
    measured value, and a known deviation's observed band; columns aligned.

    E.g. ``known deviation  walk_speed  paper [0.2, 0.3]  measured 0.18  observed [0.17, 0.19]
    claim walk.speed`` (the last column: the register claim the row tests, or walkrepro's own
    kind).
    The source and the note are left to the full rows (``--details``, and every failing row).
    """
    rows = verdict.rows
    status_w = max((len(STATUS_WORDS[r.status]) for r in rows), default=0)
    metric_w = max((len(r.metric) for r in rows), default=0)
    band_w = max((len(r.band) for r in rows), default=0)
    lines = []
    for r in rows:
        measured = r.measured_text
        observed = f"  observed {r.observed_band}" if r.observed else ""
        lines.append(
            f"  {STATUS_WORDS[r.status]:<{status_w}}  {r.metric:<{metric_w}}  paper "
            f"{r.band:<{band_w}}  measured {measured:<10}{observed}  {tag_text(r)}".rstrip()
        )
    return lines


def tag_text(row: CheckRow) -> str:
    """What a row tests, as its line shows it: ``claim <id>``, ``own <kind>`` or ``""``."""
    if row.claim is not None:
        return f"claim {row.claim}"
    return f"own {row.own}" if row.own is not None else ""


def failing_row_text(verdict: Verdict) -> list[str]:
    """Each failing row of ``verdict`` in full, as plain text: what was expected, what was
    measured (with a known deviation's observed band), the source and the note, never cut.

    A run that did not end as a run can (interrupted, error) is a failing row of its own.
    """
    texts = []
    if not verdict.run_ok:
        texts.append(f"  failed  {verdict.experiment} · run: outcome {verdict.outcome}")
    for r in verdict.rows:
        if r.status != FAIL:
            continue
        observed = f" (known deviation's observed band {r.observed_band})" if r.observed else ""
        head = f"  failed  {verdict.experiment} · {r.metric} {r.band}: measured {r.measured_text}"
        lines = [head + observed, f"          source: {r.source}"]
        if r.note:
            lines.append(f"          note: {r.note}")
        texts.append("\n".join(lines))
    return texts


def holds(op: str, measured: float, value: float | tuple[float, float]) -> bool:
    """Whether ``measured op value`` holds; NaN never holds."""
    if math.isnan(measured):
        return False
    if op == "between":
        lo, hi = value  # type: ignore[misc]
        return lo <= measured <= hi
    v = float(value)  # type: ignore[arg-type]
    return {
        "<": measured < v,
        "<=": measured <= v,
        ">": measured > v,
        ">=": measured >= v,
        "==": measured == v,
    }[op]


def _sentences(notes: list[str]) -> str:
    """The notes of a row as separate sentences: each ends with a full stop (unless it ends
    with other punctuation) before the next begins, so the spec's note and the reasons added
    here never run together."""
    parts = [n.strip() for n in notes if n and n.strip()]
    return " ".join(p if p[-1] in ".!?" else f"{p}." for p in parts)


def _has_nan(value: float | tuple[float, float]) -> bool:
    return any(math.isnan(v) for v in (value if isinstance(value, tuple) else (value,)))


#: Looks up another experiment's metric: ``(experiment, metric) -> (value, where from)``.
ReferenceLookup = Callable[[str, str], tuple[float, str]]


def no_references(experiment: str, metric: str) -> tuple[float, str]:
    """A lookup that knows no other runs (relative expectations then fail as unmeasured)."""
    return math.nan, f"no run of {experiment}"


def evaluate(
    spec: ExperimentSpec,
    metrics: dict[str, float],
    outcome: str,
    references: ReferenceLookup = no_references,
    reasons: dict[str, str] | None = None,
) -> Verdict:
    """Evaluate every expectation of ``spec`` against ``metrics``.

    Relative expectations (``relative_to``) take their value from ``references``.
    ``reasons`` says why a metric is not measurable (it then is NaN and its row fails).
    """
    why = reasons or {}
    rows = tuple(
        replace(
            _row(e, metrics.get(e.metric, math.nan), references, why.get(e.metric, "")),
            claim=e.claim,
            own=e.own,
        )
        for e in spec.expect
    )
    return Verdict(experiment=spec.name, outcome=outcome, rows=rows)


def _row(
    e: Expectation, measured: float, references: ReferenceLookup, unmeasurable: str
) -> CheckRow:
    source = e.source
    value = e.value
    notes = [e.note] if e.note else []
    if e.relative_to is not None:
        ref, origin = references(e.relative_to.experiment, e.reference_metric)
        value = e.relative_to.scale * ref
        if math.isnan(ref):
            notes.append(f"no comparison value: {origin}")
            source = f"{source} [compared with {e.relative_to.experiment}: {origin}]"
        else:
            source = (
                f"{source} [value = {e.relative_to.scale:g} × {e.relative_to.experiment}."
                f"{e.reference_metric} = {value:.4g}, from {origin}]"
            )
    assert value is not None
    if math.isnan(measured):
        notes.append(f"Not measurable: {unmeasurable or 'the metric gave no value'}")
    dev = e.known_deviation
    if dev is None:
        status = PASS if holds(e.op, measured, value) else FAIL
        if e.calibrated is not None:
            # The spec's loader refuses a row both calibrated and a known deviation.
            notes.append(
                f"Calibration criterion of {e.calibrated!r} (experiments/calibration/): the "
                "model was calibrated to meet it, so it counts apart, not as reproduced."
            )
            status = CALIBRATED if status == PASS else FAIL
        return CheckRow(e.metric, e.op, value, measured, status, source, _sentences(notes))
    if dev.observed is None:  # the spec of a log written before observed bands existed
        notes.append(f"Known deviation without an observed band (an older spec): {dev.reason}")
        return CheckRow(e.metric, e.op, value, measured, FAIL, source, _sentences(notes))
    if dev.observed == NOT_MEASURABLE:
        if math.isnan(measured):
            notes.append(f"Known deviation: {dev.reason}")
            return CheckRow(e.metric, e.op, value, measured, KNOWN, source, _sentences(notes),
                            NOT_MEASURABLE)  # fmt: skip
        met = "meets the paper" if holds(e.op, measured, value) else "misses the paper"
        notes.append(
            f"The known deviation says not measurable, but it measures {measured:g} ({met}): "
            f"the deviation has changed; update the spec. Known deviation: {dev.reason}"
        )
        return CheckRow(e.metric, e.op, value, measured, FAIL, source, _sentences(notes),
                        NOT_MEASURABLE)  # fmt: skip
    lo, hi = dev.observed
    comparable = not math.isnan(measured) and not _has_nan(value)
    if comparable and lo <= measured <= hi:
        status = KNOWN
        notes.append(f"Known deviation: {dev.reason}")
    else:
        status = FAIL
        if not comparable:
            notes.append("Known deviation, but nothing to compare with its observed band.")
        elif holds(e.op, measured, value):
            notes.append(
                "Left the known deviation's observed band and now meets the paper: the "
                "deviation may be gone; update the spec."
            )
        else:
            side = "below" if measured < lo else "above"
            notes.append(
                f"Regression: {side} the known deviation's observed band. "
                f"Known deviation: {dev.reason}"
            )
    return CheckRow(e.metric, e.op, value, measured, status, source, _sentences(notes), (lo, hi))


def write_junit(verdicts: list[Verdict], path: Path) -> None:
    """JUnit XML: one test suite per experiment, one test case per expectation.

    A known deviation is a skipped case; a calibrated row is a passing case with the
    property ``verdict = calibrated``, and every suite (and the whole report) counts them
    apart in a ``calibrated`` attribute, beside JUnit's own ``tests``, ``failures`` and
    ``skipped``.
    """
    total = count(verdicts)
    root = ET.Element(
        "testsuites",
        name="walkrepro check",
        tests=str(total.total),
        failures=str(total.failed),
        skipped=str(total.known),
        calibrated=str(total.calibrated),
    )
    for v in verdicts:
        c = count([v])
        suite = ET.SubElement(
            root,
            "testsuite",
            name=v.experiment,
            tests=str(c.total),
            failures=str(c.failed),
            skipped=str(c.known),
            calibrated=str(c.calibrated),
        )
        if not v.run_ok:  # a broken or interrupted run is one failed case, as in the counts
            run_case = ET.SubElement(suite, "testcase", classname=v.experiment, name="run")
            ET.SubElement(run_case, "failure", message=f"run outcome: {v.outcome}")
        for r in v.rows:
            case = ET.SubElement(
                suite, "testcase", classname=v.experiment, name=f"{r.metric} {r.band}"
            )
            observed = f"; observed band {r.observed_band}" if r.observed else ""
            text = f"measured {r.measured:g}{observed}; source: {r.source}; {r.note}"
            if r.status == FAIL:
                ET.SubElement(case, "failure", message=text)
            elif r.status == KNOWN:
                ET.SubElement(case, "skipped", message=text)
            elif r.status == CALIBRATED:
                props = ET.SubElement(case, "properties")
                ET.SubElement(props, "property", name="verdict", value=CALIBRATED)
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="unicode", xml_declaration=True)
