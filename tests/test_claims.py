"""Claim registers and row tags: every paper claim counted, every row saying what it tests."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.errors import SpecError, UnknownNameError
from walkrepro.evaluation.checks import CALIBRATED, FAIL, KNOWN, PASS, CheckRow, Verdict, evaluate
from walkrepro.locations import EXPERIMENTS_DIR, REFERENCES_DIR
from walkrepro.publish.claim_register import (
    DEVIATING,
    FAILED,
    NOT_COVERED,
    REPRODUCED,
    UNCHECKABLE,
    RowVerdict,
    claim_status,
    evaluate_register,
    totals,
)
from walkrepro.runs import results
from walkrepro.runs.experiment import References
from walkrepro.specs.claims import (
    Claim,
    Register,
    find_register,
    load_register,
    register_papers,
    tagging_problems,
)
from walkrepro.specs.files import load_spec, shipped_experiment_names
from walkrepro.specs.models import ExperimentSpec

runner = CliRunner()

REGISTER = """\
paper: lee2021
description: a test register
claims:
  - id: walk.speed
    where: "§VI-A"
    words: "approximately 0.11 m/s"
    kind: number
  - id: walk.no-fall
    where: "Fig. 6"
    words: "11 steps"
    kind: no_fall
  - id: hw.encoder
    where: "§V-A"
    words: "13-bit magnetic encoder"
    kind: behaviour
    uncheckable: "about the lab's hardware"
"""


def _register(tmp_path: Path, text: str = REGISTER, name: str = "lee2021") -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def _spec(rows: list[dict], sweeps: list[dict] | None = None) -> ExperimentSpec:
    """A minimal Paper I spec with the given expectation rows and map claims."""
    return ExperimentSpec.model_validate(
        {
            "name": "t",
            "description": "d",
            "paper": {"key": "lee2021", "section": "VI-A", "figure": "6"},
            "robot": "dyros_red",
            "controller": {"type": "efsm"},
            "sim": {"duration": 1.0},
            "expect": rows,
            "sweeps": sweeps or [],
        }
    )


def _row(**tag: str) -> dict:
    return {"metric": "fell", "op": "==", "value": 0, "source": "§VI-A", **tag}


def _tested(status: str, claim: str | None = "walk.speed", own: str | None = None) -> RowVerdict:
    return RowVerdict("t", "m", status, 1.0, claim, own)


# --------------------------------------------------------------------------------------
# The register file


def test_a_register_loads_with_its_claims(tmp_path: Path) -> None:
    """A valid register loads, and a claim is found by its id."""
    loaded = load_register(_register(tmp_path))
    assert [c.id for c in loaded.model.claims] == ["walk.speed", "walk.no-fall", "hw.encoder"]
    assert loaded.model.claim("hw.encoder").uncheckable == "about the lab's hardware"


def test_an_unknown_claim_id_lists_the_register(tmp_path: Path) -> None:
    """Asking for a missing id names the ids the register has."""
    with pytest.raises(UnknownNameError, match="walk.speed"):
        load_register(_register(tmp_path)).model.claim("walk.sped")


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("kind: number", "kind: numbr", "line 7, field claims.0.kind"),
        (
            "id: walk.no-fall",
            "id: walk.speed",
            "claim id names must be unique; repeated: walk.speed",
        ),
        ("id: walk.speed", "id: Walk Speed", "line 4, field claims.0.id"),
        ("paper: lee2021", "paper: nope", "unknown paper 'nope'"),
        ("    kind: no_fall\n", "    kind: no_fall\n    extra: 1\n", "field claims.1.extra"),
    ],
)
def test_a_bad_register_names_file_line_and_field(
    tmp_path: Path, old: str, new: str, message: str
) -> None:
    """A typo in a register is an error naming the file, the line and the field."""
    path = _register(tmp_path, REGISTER.replace(old, new, 1))
    with pytest.raises(SpecError, match="lee2021.yaml") as err:
        load_register(path)
    assert message in str(err.value)


def test_a_register_is_named_after_its_paper(tmp_path: Path) -> None:
    """The register of lee2021 must be lee2021.yaml."""
    with pytest.raises(SpecError, match="must be named lee2021.yaml"):
        load_register(_register(tmp_path, name="faraji"))


def test_an_unknown_register_lists_the_papers_that_have_one(tmp_path: Path) -> None:
    """find_register on a paper without a register names those that have one."""
    _register(tmp_path)
    with pytest.raises(UnknownNameError, match="lee2021"):
        find_register("jo_oh", tmp_path)


# --------------------------------------------------------------------------------------
# Tags


def test_a_row_carries_one_tag_at_most() -> None:
    """A row cannot both test a paper claim and be walkrepro's own."""
    with pytest.raises(ValueError, match="not both"):
        _spec([_row(claim="walk.speed", own="ablation")])


def test_own_takes_the_four_kinds_only() -> None:
    """own: is one of generalisation, sensitivity, ablation, sanity."""
    with pytest.raises(ValueError, match="generalisation"):
        _spec([_row(own="extrapolation")])


def test_tags_reach_the_verdict_rows() -> None:
    """An evaluated row carries its expectation's tag (check.json holds it)."""
    spec = _spec([_row(claim="walk.speed"), _row(own="sanity")])
    verdict = evaluate(spec, {"fell": 0.0}, "complete")
    assert [(r.claim, r.own) for r in verdict.rows] == [("walk.speed", None), (None, "sanity")]
    assert verdict.to_json()["rows"][0]["claim"] == "walk.speed"


def _problems(spec: ExperimentSpec, tmp_path: Path) -> list[str]:
    return tagging_problems([spec], {"lee2021": load_register(_register(tmp_path)).model})


def test_tagging_problems_is_empty_when_all_is_counted(tmp_path: Path) -> None:
    """Every row tagged, every id known, every checkable claim tested: no problem."""
    spec = _spec([_row(claim="walk.speed"), _row(claim="walk.no-fall"), _row(own="sanity")])
    assert _problems(spec, tmp_path) == []


def test_an_untagged_row_is_a_problem(tmp_path: Path) -> None:
    """A row with neither claim: nor own: is reported."""
    spec = _spec([_row(claim="walk.speed"), _row(claim="walk.no-fall"), _row()])
    assert _problems(spec, tmp_path) == [
        "t, expect row 2 (fell): untagged (claim: <id> or own: <kind>)"
    ]


def test_an_untagged_map_claim_is_a_problem(tmp_path: Path) -> None:
    """A map claim with neither claim: nor own: is reported."""
    sweep = {
        "name": "m",
        "grid": {"sim.seed": "0,1"},
        "metric": "fell",
        "claims": [{"kind": "everywhere", "region": {"metric": "fell", "op": "==", "value": 0},
                    "source": "x"}],
    }  # fmt: skip
    spec = _spec([_row(claim="walk.speed"), _row(claim="walk.no-fall")], [sweep])
    assert _problems(spec, tmp_path) == [
        "t, map m claim 0 (everywhere): untagged (claim: <id> or own: <kind>)"
    ]


def test_a_tag_to_a_missing_id_is_a_problem(tmp_path: Path) -> None:
    """claim: naming no register claim is reported with the register's file."""
    spec = _spec([_row(claim="walk.speed"), _row(claim="walk.no-fall"), _row(claim="walk.sped")])
    (problem,) = _problems(spec, tmp_path)
    assert "claim 'walk.sped' is not in the register" in problem
    assert "experiments/claims/lee2021.yaml" in problem


def test_an_uncovered_claim_without_a_reason_is_a_problem(tmp_path: Path) -> None:
    """A checkable claim no row tests is reported; an uncheckable one with its reason is not."""
    spec = _spec([_row(claim="walk.speed")])
    assert _problems(spec, tmp_path) == [
        "lee2021: claim 'walk.no-fall' (Fig. 6) is tested by no row and gives no "
        "reason (uncheckable: <why> or not_covered: <why>)"
    ]


def test_an_uncovered_claim_with_a_reason_counts_not_covered(tmp_path: Path) -> None:
    """``not_covered: <why>`` lets a checkable claim go without a row, counted not covered."""
    text = REGISTER.replace(
        "    kind: no_fall\n", '    kind: no_fall\n    not_covered: "needs a longer walk"\n'
    )
    spec = _spec([_row(claim="walk.speed")])
    registers = {"lee2021": load_register(_register(tmp_path, text)).model}
    assert tagging_problems([spec], registers) == []


def test_a_claim_cannot_be_both_uncheckable_and_not_covered(tmp_path: Path) -> None:
    text = REGISTER.replace(
        '    uncheckable: "about the lab\'s hardware"\n',
        '    uncheckable: "about the lab\'s hardware"\n    not_covered: "later"\n',
    )
    with pytest.raises(SpecError, match="not both"):
        load_register(_register(tmp_path, text))


# --------------------------------------------------------------------------------------
# Status


@pytest.mark.parametrize(
    ("statuses", "expected"),
    [
        ([PASS], REPRODUCED),
        ([PASS, PASS], REPRODUCED),
        ([PASS, CALIBRATED], CALIBRATED),
        ([PASS, KNOWN], DEVIATING),
        ([CALIBRATED, KNOWN], DEVIATING),
        ([PASS, KNOWN, FAIL], FAILED),
        ([], NOT_COVERED),
    ],
)
def test_a_claim_is_reproduced_only_when_all_its_rows_are(
    statuses: list[str], expected: str
) -> None:
    """One known deviation makes the claim deviating, one failure failed, one calibration
    criterion calibrated; with no row it is not covered."""
    claim = Claim(id="walk.speed", where="§VI-A", words="w", kind="number")
    assert claim_status(claim, [_tested(s) for s in statuses]) == expected


def test_an_uncheckable_claim_without_rows_is_uncheckable() -> None:
    """A claim the register marks uncheckable and no row tests counts as uncheckable."""
    claim = Claim(id="hw", where="§V", words="w", kind="behaviour", uncheckable="hardware")
    assert claim_status(claim, []) == UNCHECKABLE


def test_totals_count_claims_and_own_rows_apart(tmp_path: Path) -> None:
    """The register's claims are counted by status, walkrepro's own rows by verdict."""
    register = load_register(_register(tmp_path)).model
    rows = [
        _tested(PASS),
        _tested(KNOWN, claim="walk.no-fall"),
        _tested(PASS, claim=None, own="generalisation"),
        _tested(FAIL, claim=None, own="sensitivity"),
        _tested(PASS, claim=None, own=None),
    ]
    t = totals(register, rows)
    assert t.claims_text() == (
        "1 reproduced, 0 calibrated, 1 deviating, 0 failed, 0 not covered, 1 uncheckable, of 3"
    )
    assert str(t.own) == "1 reproduced, 0 calibrated, 0 known deviations, 1 failed"
    assert t.untagged == 1
    results_ = evaluate_register(register, rows)
    assert [r.status for r in results_] == [REPRODUCED, DEVIATING, UNCHECKABLE]


def test_a_row_of_another_register_claim_is_reported_unknown() -> None:
    """A tag naming an id the register lacks is listed, never counted."""
    register = Register.model_construct(
        paper="lee2021", description="", claims=[Claim(id="a", where="w", words="w", kind="number")]
    )
    t = totals(register, [_tested(PASS, claim="b")])
    assert t.unknown == ["t: b"] and t.by_status[NOT_COVERED] == 1


def test_batch_lines_count_only_the_claims_a_partial_batch_tested() -> None:
    """A batch that ran some of a paper's experiments says how many claims it tested."""
    from walkrepro.publish.claim_register import batch_lines

    if "lee2021" not in register_papers():
        pytest.skip("no Paper I register yet")
    spec = load_spec("forward_walk").spec
    claim = next(e.claim for e in spec.expect if e.claim)
    row = CheckRow("fell", "==", 0.0, 0.0, PASS, "s", "", claim=claim)
    (line,) = batch_lines([Verdict("forward_walk", "complete", (row,))])
    assert line.startswith("lee2021: the paper's claims: 1 reproduced, 0 calibrated")
    assert "tested here" in line and "not covered" not in line


# --------------------------------------------------------------------------------------
# The shipped specs, registers and references


def _shipped_specs() -> list[ExperimentSpec]:
    return [load_spec(n).spec for n in shipped_experiment_names()]


def test_every_shipped_row_tests_a_claim_or_is_walkrepros_own() -> None:
    """Every row and map claim of the shipped specs is tagged, every tag names a register
    claim, and every checkable register claim is tested by a row (docs/claims.md)."""
    registers = {k: find_register(k).model for k in register_papers()}
    assert tagging_problems(_shipped_specs(), registers) == []


def test_every_paper_has_a_register() -> None:
    """Each of the three papers has its claim register."""
    assert set(register_papers(EXPERIMENTS_DIR / "claims")) >= {"lee2021", "faraji", "jo_oh"}


@pytest.mark.parametrize("name", shipped_experiment_names())
def test_committed_verdicts_match_the_specs(name: str) -> None:
    """Each committed check.json is its spec's rows evaluated on the committed metrics: a
    restated row without a re-made reference fails here."""
    spec = load_spec(name).spec
    committed = json.loads((REFERENCES_DIR / name / results.CHECK_FILE).read_text())
    saved = results.read_metrics(REFERENCES_DIR / name / results.METRICS_FILE)
    values = {k: (math.nan if v is None else float(v)) for k, v in saved.values.items()}
    verdict = evaluate(spec, values, committed["outcome"], References(), saved.reasons)
    assert [(r["metric"], r["status"]) for r in committed["rows"]] == [
        (r.metric, r.status) for r in verdict.rows
    ]


def test_claims_command_prints_each_register_with_its_totals() -> None:
    """`walkrepro claims` prints a status per claim and each paper's totals."""
    result = runner.invoke(app, ["claims"])
    assert result.exit_code in (0, 1), result.output
    for key in register_papers():
        assert f"{key}: the paper's claims: " in result.output


def test_claims_command_names_an_unknown_paper() -> None:
    """`walkrepro claims NOPE` is a clean error listing the papers with a register."""
    result = runner.invoke(app, ["claims", "nope"])
    assert result.exit_code == 2
    assert "unknown claim register 'nope'" in result.output
