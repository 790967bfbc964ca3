"""Verdicts: expectations against metrics, known deviations, JUnit output."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from walkrepro.evaluation.checks import FAIL, KNOWN, PASS, count, evaluate, holds, write_junit
from walkrepro.specs.models import Expectation, ExperimentSpec


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


def known(low: float, high: float, **kw: object) -> Expectation:
    """``footsteps >= 11``, known to be missed, observed in [low, high]."""
    fields = {"metric": "footsteps", "op": ">=", "value": 11, "source": "s"}
    fields["known_deviation"] = {"reason": "why", "observed": [low, high]}
    fields.update(kw)
    return Expectation.model_validate({k: v for k, v in fields.items() if v is not None})


def test_failure_fails_verdict_and_known_deviation_in_its_band_does_not() -> None:
    """A missed expectation fails; a known deviation inside its observed band is reported, not failed."""
    ok = Expectation(metric="fell", op="==", value=0, source="s")
    bad = Expectation(metric="footsteps", op=">=", value=11, source="s")
    v = evaluate(make_spec(ok, bad), {"fell": 0.0, "footsteps": 3.0}, "complete")
    assert [r.status for r in v.rows] == [PASS, FAIL] and not v.passed
    v = evaluate(make_spec(ok, known(2, 4)), {"fell": 0.0, "footsteps": 3.0}, "complete")
    assert [r.status for r in v.rows] == [PASS, KNOWN] and v.passed
    assert "why" in v.rows[1].note and v.rows[1].observed == (2.0, 4.0)


def test_known_deviation_outside_its_band_fails_either_way() -> None:
    """A known deviation fails when worse than its band (regression) and when better (the deviation may be gone)."""
    worse = evaluate(make_spec(known(2, 4)), {"footsteps": 1.0}, "complete")
    assert worse.rows[0].status == FAIL and "Regression: below" in worse.rows[0].note
    better = evaluate(make_spec(known(2, 4)), {"footsteps": 12.0}, "complete")
    assert better.rows[0].status == FAIL and "update the spec" in better.rows[0].note
    above = evaluate(make_spec(known(2, 4)), {"footsteps": 5.0}, "complete")
    assert above.rows[0].status == FAIL and "above" in above.rows[0].note


def test_known_deviation_with_nan_fails() -> None:
    """A known deviation whose metric is NaN (not measurable) fails and says why."""
    v = evaluate(
        make_spec(known(2, 4)),
        {"footsteps": math.nan},
        "complete",
        reasons={"footsteps": "no steps"},
    )
    assert v.rows[0].status == FAIL and not v.passed and "no steps" in v.rows[0].note


def test_known_deviation_observed_not_measurable_holds_only_while_unmeasurable() -> None:
    """``observed: not measurable`` is a known deviation while the metric cannot be measured
    (its reason shown) and fails as soon as it can, whether the value meets the paper or not."""
    dev = {"reason": "falls during the push", "observed": "not measurable"}
    e = Expectation.model_validate(
        {"metric": "footsteps", "op": ">=", "value": 4, "source": "s", "known_deviation": dev}
    )
    v = evaluate(make_spec(e), {"footsteps": math.nan}, "fell", reasons={"footsteps": "fell"})
    assert v.rows[0].status == KNOWN and v.passed and v.rows[0].observed_band == "not measurable"
    assert "fell" in v.rows[0].note and "falls during the push" in v.rows[0].note
    for value, says in ((5.0, "meets the paper"), (1.0, "misses the paper")):
        v = evaluate(make_spec(e), {"footsteps": value}, "complete")
        assert v.rows[0].status == FAIL and not v.passed and says in v.rows[0].note
    with pytest.raises(ValueError):
        Expectation.model_validate(
            {"metric": "footsteps", "op": ">=", "value": 4, "source": "s",
             "known_deviation": {"reason": "r", "observed": "unknown"}}
        )  # fmt: skip


def test_relative_known_deviation_without_partner_fails() -> None:
    """A relative known deviation with no partner value (NaN) fails, even with its measurement in the band."""
    rel = known(2, 4, value=None, relative_to={"experiment": "other"})
    v = evaluate(make_spec(rel), {"footsteps": 3.0}, "complete")
    assert v.rows[0].status == FAIL and "no run of other" in v.rows[0].note


def test_observed_band_must_be_ordered() -> None:
    """A known deviation needs [low, high] with low <= high, and a reason."""
    with pytest.raises(ValueError, match="low <= high"):
        known(4, 2)
    with pytest.raises(ValueError):
        Expectation.model_validate(
            {"metric": "fell", "op": "==", "value": 0, "source": "s", "known_deviation": {}}
        )


def test_counts_line_and_junit_agree(tmp_path: Path) -> None:
    """The summary counts reproduced rows, known deviations and failures (a broken run is one failure), as the JUnit file does."""
    ok = Expectation(metric="fell", op="==", value=0, source="s")
    bad = Expectation(metric="footsteps", op=">=", value=11, source="s")
    a = evaluate(make_spec(ok, known(2, 4)), {"fell": 0.0, "footsteps": 3.0}, "complete")
    b = evaluate(make_spec(ok, bad), {"fell": 0.0, "footsteps": 3.0}, "interrupted")
    counts = count([a, b])
    assert (counts.reproduced, counts.calibrated, counts.known, counts.failed) == (2, 0, 1, 2)
    assert str(counts) == "2 reproduced, 0 calibrated, 1 known deviation, 2 failed"
    write_junit([a, b], tmp_path / "j.xml")
    root = ET.parse(tmp_path / "j.xml").getroot()
    assert (root.get("tests"), root.get("failures"), root.get("skipped")) == ("5", "2", "1")


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


def test_old_log_spec_with_reason_only_loads_and_fails() -> None:
    """A log written before observed bands (known_deviation: "reason") still loads, and its row fails."""
    old = Expectation.model_validate(
        {"metric": "footsteps", "op": ">=", "value": 11, "source": "s", "known_deviation": "why"}
    )
    assert old.known_deviation is not None and old.known_deviation.observed is None
    v = evaluate(make_spec(old), {"footsteps": 3.0}, "complete")
    assert v.rows[0].status == FAIL and "older spec" in v.rows[0].note


def test_summary_line_names_the_experiment_its_outcome_and_counts() -> None:
    """One experiment's line says whether it passed, its outcome and its row counts in the summary's wording."""
    from walkrepro.evaluation.checks import failing_row_text, summary_line

    ok = Expectation(metric="fell", op="==", value=0, source="s")
    bad = Expectation(metric="footsteps", op=">=", value=11, source="s")
    good = evaluate(make_spec(ok), {"fell": 0.0}, "complete")
    line = summary_line(good, 10)
    assert (
        line
        == "ok    t           complete    1 reproduced, 0 calibrated, 0 known deviations, 0 failed"
    )
    failed = evaluate(make_spec(ok, bad), {"fell": 0.0, "footsteps": 3.0}, "fell")
    assert summary_line(failed).startswith("FAIL") and "fell" in summary_line(failed)
    (text,) = failing_row_text(failed)
    assert text.splitlines() == [
        "  failed  t · footsteps >= 11: measured 3",
        "          source: s",
    ]
    assert not failing_row_text(good)
    broken = evaluate(make_spec(ok), {"fell": 0.0}, "interrupted")
    assert failing_row_text(broken) == ["  failed  t · run: outcome interrupted"]


def test_every_output_says_the_same_words_and_not_measurable() -> None:
    """A row's word is the CLI's (reproduced, calibrated, known deviation, failed) in the
    Python API too; a missing value reads ``not measurable``, never ``nan``; print(verdict)
    is the CLI's lines."""
    from walkrepro.evaluation.checks import STATUS_WORDS, claim_lines

    ok = Expectation(metric="fell", op="==", value=0, source="s")
    bad = Expectation(metric="footsteps", op=">=", value=11, source="s", note="needs steps")
    v = evaluate(make_spec(ok, bad), {"fell": 0.0}, "fell", reasons={"footsteps": "no steps"})
    assert [r.word for r in v.rows] == ["reproduced", "failed"]
    assert set(STATUS_WORDS.values()) == {"reproduced", "calibrated", "known deviation", "failed"}
    assert v.rows[1].measured_text == "not measurable"
    assert "not measurable" in claim_lines(v)[1] and "nan" not in str(v)
    assert str(v).splitlines()[1:] == claim_lines(v)
    assert "pass" not in str(v).split() and "fail" not in str(v).split()


def test_notes_are_separate_sentences() -> None:
    """The spec's note and the reasons added to it never run together."""
    e = Expectation(
        metric="footsteps", op=">=", value=11, source="s", note="steps after a fall not measurable"
    )
    v = evaluate(make_spec(e), {}, "interrupted", reasons={"footsteps": "run interrupted at 1 s"})
    assert v.rows[0].note == (
        "steps after a fall not measurable. Not measurable: run interrupted at 1 s."
    )
