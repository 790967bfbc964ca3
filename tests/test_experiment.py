"""Partners of relative expectations: the batch, the committed reference, or a paired run."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from walkrepro import RESULTS_DIR
from walkrepro.cli.batch import paired_partners
from walkrepro.cli.common import resolved_spec
from walkrepro.runs import experiment, results
from walkrepro.runs.experiment import References, partner_metric_names
from walkrepro.specs.files import experiment_names, load_spec


def committed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, values: dict, reasons: dict) -> None:
    """A committed reference results/other/metrics.json under a temporary results root."""
    monkeypatch.setattr(experiment, "REFERENCES_DIR", tmp_path)
    (tmp_path / "other").mkdir()
    results.write_metrics(tmp_path / "other" / results.METRICS_FILE, values, reasons)


def test_committed_reference_is_the_partner_and_is_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without a batch run or overrides, the partner value is the committed reference, and the origin says so."""
    committed(tmp_path, monkeypatch, {"m": 2.5}, {})
    value, origin = References()("other", "m")
    assert value == 2.5 and origin == "the committed reference results/other"


def test_committed_reference_without_the_metric_gives_a_reason(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A committed reference that could not measure the metric gives NaN with its reason."""
    committed(tmp_path, monkeypatch, {"m": math.nan}, {"m": "no steps"})
    value, origin = References()("other", "m")
    assert math.isnan(value) and "no steps" in origin
    value, origin = References()("other", "absent")
    assert math.isnan(value) and "does not hold" in origin


def test_overrides_never_use_the_committed_reference(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With overrides and no paired run, there is no partner value, and the reason names the overrides."""
    committed(tmp_path, monkeypatch, {"m": 2.5}, {})
    value, origin = References(overrides=["sim.seed=3"], unpaired={"other": "bad field"})(
        "other", "m"
    )
    assert math.isnan(value) and "sim.seed=3" in origin and "bad field" in origin


def test_recheck_finds_the_partner_run_with_the_same_overrides(tmp_path: Path) -> None:
    """Re-checking a run looks for the partner's latest run made with the same overrides only."""
    for name, overrides in (
        ("20260101T000000Z-aaaaaa", ["sim.seed=3"]),
        ("20260102T000000Z-bbbbbb", []),
    ):
        run = tmp_path / "other" / name
        run.mkdir(parents=True)
        (run / results.RUN_FILE).write_text(json.dumps({"overrides": overrides}))
    found = experiment._latest_run_with(tmp_path, "other", ["sim.seed=3"])
    assert found is not None and found.name.endswith("aaaaaa")
    assert experiment._latest_run_with(tmp_path, "other", ["sim.seed=4"]) is None


def test_partner_metrics_are_reported_by_the_partner() -> None:
    """An experiment's run reports the metrics that other experiments' relative rows read from it."""
    needed = partner_metric_names("obstacle_4cm_no_impedance")
    assert "peak_landing_force:right_foot" in needed
    assert "swing_z_settling_time:right_foot" in needed
    assert "mean_abs_pelvis_speed:2.5-10.5" in partner_metric_names("continuous_drag")


def test_overrides_pair_the_partner_or_say_why_not() -> None:
    """With --set, a relative row's partner runs in the same batch with the same overrides; an override it cannot take is a reason."""
    overrides = ["sim.seed=3"]
    specs = {"obstacle_4cm": resolved_spec("obstacle_4cm", overrides)}
    partners, unpaired = paired_partners(specs, overrides)
    assert partners == ["obstacle_4cm_no_impedance"] and not unpaired
    assert paired_partners(specs, []) == ([], {})
    odd = ["world.obstacles.0.tilt_x_deg=3"]
    specs = {"continuous_drag_stepping": resolved_spec("continuous_drag_stepping", [])}
    partners, unpaired = paired_partners(specs, odd)
    assert partners == [] and "continuous_drag" in unpaired


@pytest.mark.parametrize("name", experiment_names())
def test_committed_references_hold_what_relative_rows_need(name: str) -> None:
    """Every relative expectation finds its partner's metric, measured, in the committed reference."""
    for e in load_spec(name).spec.expect:
        if e.relative_to is None:
            continue
        path = RESULTS_DIR / e.relative_to.experiment / results.METRICS_FILE
        saved = results.read_metrics(path)
        assert saved.values.get(e.reference_metric) is not None, (path, e.reference_metric)
