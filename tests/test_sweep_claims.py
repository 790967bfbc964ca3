"""Tests of map claims: pure functions over made-up cells tables."""

from __future__ import annotations

import itertools
import math

import pytest

from walkrepro.evaluation.checks import FAIL, KNOWN, PASS
from walkrepro.specs.sweeps import SweepClaim, SweepSpec
from walkrepro.studies.sweep.claims import evaluate_claim, in_region, matches

FIELDS = ("height", "tilt", "impedance")
HEIGHTS, TILTS = (0.02, 0.04, 0.06), (0, 10, 20)


def table(falls: set[tuple[float, int, bool]], errors: frozenset = frozenset()) -> list[dict]:
    """A 3×3×2 table: every cell stands except those in ``falls`` (and ``errors`` errored)."""
    rows = []
    for k, (h, t, imp) in enumerate(itertools.product(HEIGHTS, TILTS, (True, False))):
        outcome = (
            "error" if (h, t, imp) in errors else ("fell" if (h, t, imp) in falls else "complete")
        )
        fell = math.nan if outcome == "error" else float(outcome == "fell")
        rows.append(
            {"cell": k, "height": h, "tilt": t, "impedance": imp, "outcome": outcome, "fell": fell}
        )
    return rows


CONTAINS = SweepClaim.model_validate(
    {
        "kind": "contains",
        "region": {"metric": "fell", "op": "==", "value": 0},
        "where": {"impedance": True},
        "contains": {"impedance": False},
        "source": "Jo & Oh §IV",
    }
)


def test_contains_passes_when_the_with_region_is_larger() -> None:
    """With impedance standing wherever the robot stands without it, the claim holds."""
    falls = {(0.06, 20, True), (0.06, 20, False), (0.06, 10, False), (0.04, 20, False)}
    row = evaluate_claim(table(falls), FIELDS, CONTAINS, "m")
    assert row.status == PASS and row.measured == 0
    assert "8 of 9 cells where impedance=true, 6 of 9 where impedance=false" in row.note


def test_contains_fails_when_the_without_region_is_not_contained() -> None:
    """A cell that stands without impedance but falls with it contradicts the claim."""
    falls = {(0.04, 10, True), (0.06, 20, False)}
    row = evaluate_claim(table(falls), FIELDS, CONTAINS, "m")
    assert row.status == FAIL
    assert row.measured == 1
    assert "(height=0.04, tilt=10)" in row.note


def test_an_errored_cell_makes_contains_unmeasurable() -> None:
    """A with-impedance cell that errored cannot confirm containment: the claim fails, saying why."""
    row = evaluate_claim(table(set(), frozenset({(0.02, 0, True)})), FIELDS, CONTAINS, "m")
    assert row.status == FAIL and row.measured == 0
    assert "not measurable" in row.note and "error" in row.note


def test_missing_cells_make_a_claim_unmeasurable() -> None:
    """A table with fewer rows than the grid's cells cannot pass."""
    rows = table(set())[:-1]
    row = evaluate_claim(rows, FIELDS, CONTAINS, "m", n_cells=18)
    assert row.status == FAIL and "1 of 18 cells missing" in row.note


def known_claim(low: float, high: float) -> SweepClaim:
    return SweepClaim.model_validate(
        {
            **CONTAINS.model_dump(),
            "known_deviation": {"reason": "the QP alone is robust too", "observed": [low, high]},
        }
    )


def test_known_deviation_claim_in_its_band_is_reported_not_failed() -> None:
    """A claim marked known_deviation whose contradicting cells stay in its observed band is a known deviation with its reason."""
    row = evaluate_claim(table({(0.04, 10, True)}), FIELDS, known_claim(1, 1), "m")
    assert row.status == KNOWN and "the QP alone is robust too" in row.note
    assert row.observed == (1.0, 1.0)


def test_known_deviation_claim_outside_its_band_fails() -> None:
    """A known-deviation claim fails with more contradicting cells than observed, and with fewer (it may hold now)."""
    more = evaluate_claim(
        table({(0.04, 10, True), (0.04, 20, True)}), FIELDS, known_claim(1, 1), "m"
    )
    assert more.status == FAIL and "more" in more.note
    fewer = evaluate_claim(table(set()), FIELDS, known_claim(1, 1), "m")
    assert fewer.status == FAIL and "update the spec" in fewer.note


EVERYWHERE = SweepClaim.model_validate(
    {
        "kind": "everywhere",
        "region": {"metric": "fell", "op": "==", "value": 0},
        "where": {"height": {"op": "<=", "value": 0.04}},
        "source": "every push below X is recovered at every phase",
    }
)


def test_everywhere_holds_below_the_threshold_only() -> None:
    """Falls above the threshold do not matter; one fall below it fails the claim."""
    assert evaluate_claim(table({(0.06, 0, True)}), FIELDS, EVERYWHERE, "m").status == PASS
    row = evaluate_claim(table({(0.04, 20, False)}), FIELDS, EVERYWHERE, "m")
    assert row.status == FAIL and row.measured == 1
    assert "height=0.04, tilt=20, impedance=false" in row.note


def test_selectors_and_regions() -> None:
    """Selectors compare numbers with tolerance and booleans exactly; unmeasured cells are None."""
    row = {"height": 0.04 + 1e-15, "impedance": True, "outcome": "complete", "fell": 0.0}
    assert matches(row, {"height": 0.04, "impedance": True})
    assert not matches(row, {"impedance": False})
    assert matches(row, {"height": {"op": "between", "value": [0.03, 0.05]}})
    assert in_region(row, CONTAINS) is True
    assert in_region({**row, "outcome": "crashed"}, CONTAINS) is None


def test_claim_kinds_are_validated() -> None:
    """A contains claim needs its inner selector."""
    with pytest.raises(ValueError, match="needs contains"):
        SweepClaim.model_validate(
            {
                "kind": "contains",
                "region": {"metric": "fell", "op": "==", "value": 0},
                "source": "x",
            }
        )


EXCEEDS = SweepClaim.model_validate({**CONTAINS.model_dump(), "kind": "exceeds"})


def test_exceeds_passes_when_the_with_region_is_strictly_larger() -> None:
    """With impedance standing wherever the robot stands without it, and somewhere more, "larger" holds."""
    falls = {(0.06, 20, True), (0.06, 20, False), (0.06, 10, False)}
    row = evaluate_claim(table(falls), FIELDS, EXCEEDS, "m")
    assert row.status == PASS and row.measured == 0
    assert "1 only where impedance=true" in row.note and "⊋" in row.metric


def test_exceeds_fails_when_the_regions_are_equal() -> None:
    """Equal regions contain each other, but neither is larger: the claim fails with one contradiction."""
    falls = {(0.06, 20, True), (0.06, 20, False)}
    row = evaluate_claim(table(falls), FIELDS, EXCEEDS, "m")
    assert row.status == FAIL and row.measured == 1
    assert "no cell where impedance=true lies in the region and its partner does not" in row.note


def test_exceeds_fails_on_a_made_up_map_where_with_does_not_contain_without() -> None:
    """A larger with-impedance region that misses a cell the without region holds is not "larger": it fails at that cell."""
    # With impedance 7 of 9 stand (falls at 6 cm tilted 10° and 20°), without also 7 of 9
    # (falls at 4 and 6 cm untilted): each region holds cells the other does not.
    falls = {(0.06, 10, True), (0.06, 20, True), (0.04, 0, False), (0.06, 0, False)}
    row = evaluate_claim(table(falls), FIELDS, EXCEEDS, "m")
    assert row.status == FAIL and row.measured == 2
    assert "contradicted at (height=0.06, tilt=10); (height=0.06, tilt=20)" in row.note
    assert evaluate_claim(table(falls), FIELDS, CONTAINS, "m").status == FAIL


FAILS_AT = SweepClaim.model_validate(
    {
        "kind": "everywhere",
        "region": {"metric": "stepped_on_off", "op": "==", "value": 0},
        "where": {"height": {"op": ">=", "value": 0.05}, "tilt": 0, "impedance": False},
        "source": "Jo & Oh §IV-A: it is difficult to be overcome with the 5cm height obstacle",
    }
)


def test_a_failure_statement_is_everywhere_with_the_failed_region() -> None:
    """ "Fails at 5 cm and above" holds when every such cell failed, and is contradicted by one that succeeded."""
    rows = table(set())
    for r in rows:  # success = stepped on and off; fails from 5 cm without impedance
        r["stepped_on_off"] = float(r["impedance"] or r["height"] < 0.05)
    assert evaluate_claim(rows, FIELDS, FAILS_AT, "m").status == PASS
    for r in rows:
        if r["height"] == 0.06 and r["tilt"] == 0:
            r["stepped_on_off"] = 1.0
    row = evaluate_claim(rows, FIELDS, FAILS_AT, "m")
    assert row.status == FAIL and row.measured == 1
    assert "(height=0.06, tilt=0, impedance=false)" in row.note


def test_an_exceeds_claim_needs_its_inner_selector() -> None:
    """Like contains, an exceeds claim names the cells it is compared with."""
    with pytest.raises(ValueError, match="'exceeds' claim needs contains"):
        SweepClaim.model_validate(
            {"kind": "exceeds", "region": {"metric": "fell", "op": "==", "value": 0}, "source": "x"}
        )


# ---- paired claims: a metric against its value at the partner cell ----------------------------

PAIRED = SweepClaim.model_validate(
    {
        "kind": "paired",
        "region": {"metric": "speed", "op": "<", "value": 1.0},
        "where": {"stepping": True},
        "than": {"stepping": False},
        "source": "Faraji, Continuous Pushes",
    }
)
FORCES = (2.0, 4.0, 6.0, 8.0)


def drag_table(speeds: dict[tuple[float, bool], float], fell: frozenset = frozenset()) -> list:
    """Cells over force × stepping with a mean speed each; ``fell`` cells have none."""
    rows = []
    for k, (f, step) in enumerate(itertools.product(FORCES, (True, False))):
        down = (f, step) in fell
        rows.append(
            {
                "cell": k,
                "force": f,
                "stepping": step,
                "outcome": "fell" if down else "complete",
                "fell": float(down),
                "speed": math.nan if down else speeds[(f, step)],
            }
        )
    return rows


def slower_with_stepping(factor: float) -> dict[tuple[float, bool], float]:
    """Speeds growing with the force; with stepping ``factor`` × the open-loop speed."""
    return {(f, s): 0.03 * f * (factor if s else 1.0) for f in FORCES for s in (True, False)}


def test_paired_holds_when_every_cell_is_below_its_partner() -> None:
    """Stepping slower at every force: no contradicting cell."""
    row = evaluate_claim(drag_table(slower_with_stepping(0.7)), ("force", "stepping"), PAIRED, "m")
    assert row.status == PASS and row.measured == 0
    assert "holds at 4 of 4 cells where stepping=true" in row.note


def test_paired_fails_where_a_cell_is_not_below_its_partner() -> None:
    """One force where stepping is faster: one contradicting cell, named with both values."""
    speeds = slower_with_stepping(0.7)
    speeds[(4.0, True)] = 0.2
    row = evaluate_claim(drag_table(speeds), ("force", "stepping"), PAIRED, "m")
    assert row.status == FAIL and row.measured == 1
    assert "(force=4.0) (0.2 against 0.12)" in row.note


def test_paired_scale_sets_how_much_lower() -> None:
    """``value`` scales the partner: 0.8× slower at every force fails "below 0.5×"."""
    claim = PAIRED.model_copy(update={"region": PAIRED.region.model_copy(update={"value": 0.5})})
    row = evaluate_claim(drag_table(slower_with_stepping(0.8)), ("force", "stepping"), claim, "m")
    assert row.status == FAIL and row.measured == 4


def test_paired_partner_without_a_measurement_is_unknown() -> None:
    """A partner that fell has no speed: the claim cannot hold there, and says why."""
    rows = drag_table(slower_with_stepping(0.7), fell=frozenset({(8.0, False)}))
    row = evaluate_claim(rows, ("force", "stepping"), PAIRED, "m")
    assert row.status == FAIL and row.measured == 0
    assert "(force=8.0) where stepping=false (fell: no speed)" in row.note
    # Restricting the claim to the forces both modes survive makes it measurable again.
    where = {"stepping": True, "force": {"op": "<=", "value": 6.0}}
    row = evaluate_claim(
        rows, ("force", "stepping"), PAIRED.model_copy(update={"where": where}), "m"
    )
    assert row.status == PASS and "3 of 3" in row.note


@pytest.mark.parametrize(
    "claim, message",
    [
        ({"kind": "paired", "region": {"metric": "s", "op": "<", "value": 1}}, "needs than"),
        (
            {
                "kind": "paired",
                "region": {"metric": "s", "op": "between", "value": [0, 1]},
                "than": {"a": 1},
            },
            "single-number op",
        ),
        (
            {
                "kind": "everywhere",
                "region": {"metric": "s", "op": "<", "value": 1},
                "than": {"a": 1},
            },
            "kind paired only",
        ),
    ],
)
def test_paired_claims_are_validated(claim: dict, message: str) -> None:
    """A paired claim without a partner selector, or with a band, is a spec error."""
    with pytest.raises(ValueError, match=message):
        SweepClaim.model_validate({**claim, "source": "x"})


@pytest.mark.parametrize(
    "claim",
    [
        PAIRED.model_copy(update={"where": {"stepping": True, "force": {"op": ">", "value": 9.0}}}),
        SweepClaim.model_validate(
            {
                "kind": "everywhere",
                "region": {"metric": "fell", "op": "==", "value": 0},
                "where": {"force": {"op": ">", "value": 9.0}},
                "source": "x",
            }
        ),
        SweepClaim.model_validate(
            {
                "kind": "contains",
                "region": {"metric": "fell", "op": "==", "value": 0},
                "where": {"stepping": True},
                "contains": {"force": 9.5},
                "source": "x",
            }
        ),
    ],
    ids=["paired", "everywhere", "contains"],
)
def test_a_claim_over_no_cells_fails(claim: SweepClaim) -> None:
    """A selector that no cell of the map matches (a force the grid does not hold) leaves
    nothing to contradict the claim: it fails and says which selector is empty."""
    row = evaluate_claim(drag_table(slower_with_stepping(0.7)), ("force", "stepping"), claim, "m")
    assert row.status == FAIL and row.measured == 0
    assert "no cell of the map where" in row.note


# ---- mirrored pairing: forward against backward pushes ---------------------------------------

PUSH_FIELDS = ("push_impulse", "start")
IMPULSES, ONSETS = (-8, -6, -4, 4, 6, 8), (4.0, 4.1)


def push_table(recovered: set[tuple[int, float]]) -> list[dict]:
    """Pushes of ±4-8 N·s at two onsets: recovered where listed, else fallen."""
    rows = []
    for k, (p, s) in enumerate(itertools.product(IMPULSES, ONSETS)):
        fell = float((p, s) not in recovered)
        outcome = "fell" if fell else "complete"
        rows.append({"cell": k, "push_impulse": p, "start": s, "outcome": outcome, "fell": fell})
    return rows


MIRRORED = SweepClaim.model_validate(
    {
        "kind": "exceeds",
        "region": {"metric": "fell", "op": "==", "value": 0},
        "where": {"push_impulse": {"op": ">", "value": 0}},
        "contains": {"push_impulse": {"op": "<", "value": 0}},
        "mirror": "push_impulse",
        "source": "Paper II, Moderate Pushes",
    }
)
#: Every push to 6 N·s recovered both ways at both onsets.
BOTH_WAYS = {(p, s) for p in (-6, -4, 4, 6) for s in ONSETS}


def test_mirrored_forward_pushes_recovered_stronger() -> None:
    """Forward pushes recovered to 8 N·s, backward ones to 6: the forward region is larger."""
    row = evaluate_claim(push_table(BOTH_WAYS | {(8, 4.0)}), PUSH_FIELDS, MIRRORED, "m")
    assert row.status == PASS and row.measured == 0
    assert "mirrored in push_impulse" in row.metric
    assert "5 of 6 cells where push_impulse > 0, 4 of 6 where push_impulse < 0; 1 only" in row.note


def test_mirrored_equal_limits_are_not_stronger() -> None:
    """Pushes recovered to 6 N·s both ways: forward is not stronger, the claim fails."""
    row = evaluate_claim(push_table(BOTH_WAYS), PUSH_FIELDS, MIRRORED, "m")
    assert row.status == FAIL and row.measured == 1


def test_mirrored_backward_push_recovered_alone_contradicts() -> None:
    """A backward 8 N·s push recovered where its forward mirror falls contradicts the claim,
    named by the backward cell."""
    recovered = BOTH_WAYS | {(8, 4.0), (-8, 4.1)}
    row = evaluate_claim(push_table(recovered), PUSH_FIELDS, MIRRORED, "m")
    assert row.status == FAIL and row.measured == 1
    assert "contradicted at (push_impulse=-8, start=4.1)" in row.note


def test_without_mirror_opposite_pushes_are_not_paired() -> None:
    """Without ``mirror`` the cells pair by onset alone, not forward with backward: the claim
    that holds mirrored fails."""
    plain = SweepClaim.model_validate({**MIRRORED.model_dump(), "mirror": None})
    row = evaluate_claim(push_table(BOTH_WAYS | {(8, 4.0)}), PUSH_FIELDS, plain, "m")
    assert row.status == FAIL and "mirrored" not in row.metric


def test_mirror_needs_a_pairing_kind() -> None:
    """An ``everywhere`` claim pairs nothing, so it cannot mirror."""
    with pytest.raises(ValueError, match="'mirror' pairs cells"):
        SweepClaim.model_validate(
            {**CONTAINS.model_dump(), "kind": "everywhere", "contains": None, "mirror": "height"}
        )


def test_mirror_names_a_grid_field() -> None:
    """A map whose claim mirrors a field it does not sweep is a spec error naming its grid."""
    with pytest.raises(ValueError, match="not a grid field of map 'm' \\(start\\)"):
        SweepSpec.model_validate(
            {"name": "m", "grid": {"start": "4.0,4.1"}, "claims": [MIRRORED.model_dump()]}
        )


def unmeasurable_claim(band: tuple[int, int] | None) -> SweepClaim:
    deviation = {"reason": "the cells from 0.04 m fall first", "observed": [0, 0]}
    if band is not None:
        deviation["unmeasurable_cells"] = list(band)
    return SweepClaim.model_validate({**CONTAINS.model_dump(), "known_deviation": deviation})


def test_declared_unmeasurable_cells_make_a_known_deviation() -> None:
    """Cells whose region cannot be measured (errored here) are a known deviation only when the
    claim declares their count, and only at that count."""
    errors = frozenset({(0.04, 0, True), (0.06, 0, True)})
    row = evaluate_claim(table(set(), errors), FIELDS, unmeasurable_claim((2, 2)), "m")
    assert row.status == KNOWN
    undeclared = evaluate_claim(table(set(), errors), FIELDS, unmeasurable_claim(None), "m")
    assert undeclared.status == FAIL and "2 cells not measurable" in undeclared.note
    fewer = evaluate_claim(table(set(), errors), FIELDS, unmeasurable_claim((3, 3)), "m")
    assert fewer.status == FAIL and "declared (3, 3)" in fewer.note
    measurable = evaluate_claim(table(set()), FIELDS, unmeasurable_claim((2, 2)), "m")
    assert measurable.status == FAIL


def test_declared_unmeasurable_cells_do_not_excuse_missing_cells() -> None:
    """A missing cell fails the claim whatever the known deviation declares."""
    errors = frozenset({(0.04, 0, True), (0.06, 0, True)})
    rows = table(set(), errors)[:-1]
    row = evaluate_claim(rows, FIELDS, unmeasurable_claim((2, 3)), "m", n_cells=18)
    assert row.status == FAIL and "missing cells" in row.note


def test_an_expectation_cannot_declare_unmeasurable_cells() -> None:
    """unmeasurable_cells is a map claim's; an expectation says observed: not measurable."""
    from pydantic import ValidationError

    from walkrepro.specs.models import Expectation

    with pytest.raises(ValidationError, match="unmeasurable_cells belongs to a map claim"):
        Expectation.model_validate(
            {
                "metric": "fell",
                "op": "==",
                "value": 0,
                "source": "x",
                "known_deviation": {
                    "reason": "r",
                    "observed": [1, 1],
                    "unmeasurable_cells": [1, 1],
                },
            }
        )
