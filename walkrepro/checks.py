"""The paper's expectations evaluated against a run's metrics: a verdict table.

An expectation passes when ``measured op value`` holds. A missing measurement (NaN) fails.
An expectation marked ``known_deviation`` is evaluated and shown as such, with its reason;
it does not fail the verdict, and it is never turned into a pass.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from walkrepro.spec import Expectation, ExperimentSpec

PASS, FAIL, KNOWN = "pass", "fail", "known deviation"


@dataclass(frozen=True)
class CheckRow:
    """One evaluated expectation.

    Attributes:
        metric: metric name (with argument).
        op: comparison operator.
        paper: the expected value or band, as written in the spec.
        measured: the run's value (NaN if unavailable).
        status: ``pass``, ``fail`` or ``known deviation``.
        source: where in the paper the expectation comes from.
        note: free text from the spec, plus the deviation reason if any.
    """

    metric: str
    op: str
    paper: float | tuple[float, float]
    measured: float
    status: str
    source: str
    note: str

    @property
    def band(self) -> str:
        """The expectation as text, e.g. ``between 0.07 and 0.16``."""
        if self.op == "between":
            lo, hi = self.paper  # type: ignore[misc]
            return f"[{lo:g}, {hi:g}]"
        return f"{self.op} {self.paper:g}"


@dataclass(frozen=True)
class Verdict:
    """All rows of one run, and the outcome of the run itself."""

    experiment: str
    outcome: str
    rows: tuple[CheckRow, ...]

    @property
    def passed(self) -> bool:
        """No failing row, and the run was not interrupted or broken."""
        return self.outcome in ("complete", "fell") and all(r.status != FAIL for r in self.rows)

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
        }


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
) -> Verdict:
    """Evaluate every expectation of ``spec`` against ``metrics``.

    Relative expectations (``relative_to``) take their value from ``references``.
    """
    rows = tuple(_row(e, metrics.get(e.metric, math.nan), references) for e in spec.expect)
    return Verdict(experiment=spec.name, outcome=outcome, rows=rows)


def _row(e: Expectation, measured: float, references: ReferenceLookup) -> CheckRow:
    source = e.source
    value = e.value
    if e.relative_to is not None:
        ref, origin = references(e.relative_to.experiment, e.reference_metric)
        value = e.relative_to.scale * ref
        source = (
            f"{source} [value = {e.relative_to.scale:g} × {e.relative_to.experiment}."
            f"{e.reference_metric} = {value:.4g}, from {origin}]"
        )
    assert value is not None
    ok = holds(e.op, measured, value)
    note = e.note
    if e.known_deviation:
        status = PASS if ok else KNOWN
        if not ok:
            note = f"{note} Known deviation: {e.known_deviation}".strip()
    else:
        status = PASS if ok else FAIL
    return CheckRow(e.metric, e.op, value, measured, status, source, note)


def write_junit(verdicts: list[Verdict], path: Path) -> None:
    """JUnit XML: one test suite per experiment, one test case per expectation."""
    root = ET.Element("testsuites", name="walkrepro check")
    for v in verdicts:
        failures = sum(r.status == FAIL for r in v.rows) + (
            0 if v.outcome in ("complete", "fell") else 1
        )
        suite = ET.SubElement(
            root, "testsuite", name=v.experiment, tests=str(len(v.rows) + 1), failures=str(failures)
        )
        run_case = ET.SubElement(suite, "testcase", classname=v.experiment, name="run")
        if v.outcome not in ("complete", "fell"):
            ET.SubElement(run_case, "failure", message=f"run outcome: {v.outcome}")
        for r in v.rows:
            case = ET.SubElement(
                suite, "testcase", classname=v.experiment, name=f"{r.metric} {r.band}"
            )
            text = f"measured {r.measured:g}; source: {r.source}; {r.note}"
            if r.status == FAIL:
                ET.SubElement(case, "failure", message=text)
            elif r.status == KNOWN:
                ET.SubElement(case, "skipped", message=text)
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="unicode", xml_declaration=True)
