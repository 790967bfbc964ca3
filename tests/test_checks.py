"""Verdicts: expectations against metrics, known deviations, JUnit output."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from walkrepro.checks import FAIL, KNOWN, PASS, evaluate, holds, write_junit
from walkrepro.spec import Expectation, ExperimentSpec


def make_spec(*expect: Expectation) -> ExperimentSpec:
    return ExperimentSpec.model_validate(
        {
            "name": "t",
            "description": "d",
            "paper": {"key": "walkrepro"},
            "robot": "dyros_red",
            "controller": {"type": "posture"},
            "sim": {"duration": 1.0},
            "expect": [e.model_dump() for e in expect],
        }
    )


def test_operators() -> None:
    """Each operator compares as written, and NaN never satisfies any."""
    assert holds("<", 1, 2) and not holds("<", 2, 2)
    assert holds("<=", 2, 2) and holds(">=", 2, 2) and not holds(">", 2, 2)
    assert holds("==", 0, 0) and not holds("==", 0.1, 0)
    assert holds("between", 0.1, (0.07, 0.16)) and not holds("between", 0.2, (0.07, 0.16))
    for op, value in (("<", 1.0), (">", 1.0), ("between", (0.0, 1.0)), ("==", 0.0)):
        assert not holds(op, math.nan, value)


def test_failure_fails_verdict_and_known_deviation_does_not() -> None:
    """A missed expectation fails; a missed known deviation is reported but not failed."""
    ok = Expectation(metric="fell", op="==", value=0, source="s")
    bad = Expectation(metric="footsteps", op=">=", value=11, source="s")
    known = Expectation(metric="footsteps", op=">=", value=11, source="s", known_deviation="why")
    v = evaluate(make_spec(ok, bad), {"fell": 0.0, "footsteps": 3.0}, "complete")
    assert [r.status for r in v.rows] == [PASS, FAIL] and not v.passed
    v = evaluate(make_spec(ok, known), {"fell": 0.0, "footsteps": 3.0}, "complete")
    assert [r.status for r in v.rows] == [PASS, KNOWN] and v.passed
    assert "why" in v.rows[1].note


def test_missing_metric_and_broken_run_fail() -> None:
    """A metric absent from the results fails, and an interrupted run never passes."""
    ok = Expectation(metric="fell", op="==", value=0, source="s")
    assert not evaluate(make_spec(ok), {}, "complete").passed
    assert not evaluate(make_spec(ok), {"fell": 0.0}, "interrupted").passed


def test_junit_report(tmp_path: Path) -> None:
    """The JUnit file has one failing case per failed expectation."""
    bad = Expectation(metric="footsteps", op=">=", value=11, source="s")
    v = evaluate(make_spec(bad), {"footsteps": 3.0}, "complete")
    write_junit([v], tmp_path / "j.xml")
    root = ET.parse(tmp_path / "j.xml").getroot()
    assert root.find("testsuite").get("failures") == "1"
    assert len(root.findall(".//failure")) == 1


def test_relative_expectation_takes_value_from_the_other_run() -> None:
    """A relative expectation compares with scale × the other experiment's metric, and says where it came from."""
    rel = Expectation.model_validate(
        {
            "metric": "footsteps",
            "op": ">=",
            "relative_to": {"experiment": "in_place", "scale": 2},
            "source": "s",
        }
    )
    lookup = lambda experiment, metric: (3.0, f"run of {experiment}")  # noqa: E731
    v = evaluate(make_spec(rel), {"footsteps": 6.0}, "complete", lookup)
    assert v.passed and v.rows[0].paper == 6.0 and "in_place" in v.rows[0].source
    v = evaluate(make_spec(rel), {"footsteps": 5.9}, "complete", lookup)
    assert not v.passed
    # Without a run of the other experiment the expectation cannot pass.
    assert not evaluate(make_spec(rel), {"footsteps": 6.0}, "complete").passed


def test_relative_expectation_needs_exactly_one_value() -> None:
    """An expectation with both or neither of value and relative_to is rejected."""
    import pydantic
    import pytest

    for bad in ({}, {"value": 1, "relative_to": {"experiment": "x"}}):
        with pytest.raises(pydantic.ValidationError, match="exactly one of value and relative_to"):
            Expectation.model_validate({"metric": "fell", "op": "<", "source": "s", **bad})
