"""Declared calibration: the file, the references, the rules, the searches, the counts."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from typer.testing import CliRunner

from walkrepro.errors import SpecError, WalkreproError
from walkrepro.evaluation.checks import CALIBRATED, FAIL, count, evaluate, write_junit
from walkrepro.specs import calibration_files as calibration_model
from walkrepro.specs.calibration_files import (
    CALIBRATION_DIR,
    calibration_papers,
    dump_calibration,
    load_calibration,
    with_results,
)
from walkrepro.specs.files import load_spec
from walkrepro.studies.calibration.rules import check_consistency
from walkrepro.studies.calibration.run import CalibrateOptions, EngineEvaluators, calibrate, compare
from walkrepro.studies.calibration.search import CalibrationFailed, RootProblem, find_root, split
from walkrepro.studies.sweep.cells import CellResult, CellTask
from walkrepro.studies.sweep.engines import ProcessEngine

METRIC = "mean_forward_speed:0.1-0.3"

SPEC = """\
name: tiny
description: a short standing run
paper: {key: walkrepro}
robot: dyros_red
controller:
  type: posture
  params:
    kp: {calibrated: gain}
sim: {timestep: 0.0005, control_period: 0.001, duration: 0.3}
expect:
  - {metric: fell, op: "==", value: 0, source: test}
  - {metric: "mean_forward_speed:0.1-0.3", op: between, value: [-0.01, 0.01], source: set-up, calibrated: gain}
"""

CALIBRATION = """\
paper: walkrepro
description: a test calibration
parameters:
- name: gain
  set: controller.params.kp
  unit: Nm/rad
  range: [0.0, 1000.0]
  criterion: {kind: setup_statement, quote: the robot stands still, section: test}
  experiment: tiny
  metric: "mean_forward_speed:0.1-0.3"
  target: {value: 0.0, tolerance: 0.01}
  search: {method: root, bracket: [100.0, 600.0], xtol: 1.0}
  result: RESULT
"""

RESULT = (
    "{value: 321.5, measured: 0.001, evaluations: [[100.0, -1.0]], provenance: {commit: abc, "
    "date: '2026-01-01T00:00:00+00:00', mujoco: '1', pinocchio: '1', numpy: '1', python: '3'}}"
)


def write_tree(
    root: Path, spec: str = SPEC, calibration: str = CALIBRATION, result: str = RESULT
) -> Path:
    """A folder of specs with its own calibration/walkrepro.yaml; returns the spec's path."""
    (root / "calibration").mkdir(parents=True, exist_ok=True)
    (root / "calibration" / "walkrepro.yaml").write_text(calibration.replace("RESULT", result))
    path = root / "tiny.yaml"
    path.write_text(spec)
    return path


def speed_of_gain(kp: float) -> float:
    """The fake criterion: a speed [m/s] that crosses zero at kp = 321.0 Nm/rad."""
    return (kp - 321.0) / 1000.0


def fake_cell(task: CellTask) -> CellResult:
    """A sweep cell that computes the fake criterion from its resolved spec (no physics)."""
    kp = float(task.spec.controller.params["kp"])
    return CellResult(task.index, "complete", "fake", metrics={METRIC: speed_of_gain(kp)})


# --------------------------------------------------------------------------------------
# References and marks in specs


def test_a_reference_resolves_to_the_committed_value(tmp_path: Path) -> None:
    """`{calibrated: gain}` in a spec becomes the calibration file's committed result.value."""
    loaded = load_spec(write_tree(tmp_path))
    assert loaded.spec.controller.params["kp"] == 321.5


def test_set_overrides_a_reference(tmp_path: Path) -> None:
    """`--set` replaces a calibrated reference, as it replaces any value."""
    loaded = load_spec(write_tree(tmp_path), ["controller.params.kp=250"])
    assert loaded.spec.controller.params["kp"] == 250


def test_an_unknown_reference_names_file_line_and_field(tmp_path: Path) -> None:
    """A reference to no parameter of the calibration file is an error at its line."""
    path = write_tree(tmp_path, spec=SPEC.replace("{calibrated: gain}", "{calibrated: gian}"))
    with pytest.raises(WalkreproError) as exc:
        load_spec(path)
    text = str(exc.value)
    assert "tiny.yaml, line 8, field controller.params.kp" in text and "'gian'" in text, text
    assert "gain" in text, text  # the valid names


def test_a_reference_without_a_result_is_an_error(tmp_path: Path) -> None:
    """A parameter with `result: null` cannot be used yet; the error says how to compute it."""
    path = write_tree(tmp_path, result="null")
    with pytest.raises(SpecError, match=r"line 8.*no result yet.*walkrepro calibrate walkrepro"):
        load_spec(path)


def test_a_reference_without_a_calibration_file_is_an_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A paper without a calibration file (beside the spec or shipped) gives no calibrated
    values."""
    path = write_tree(tmp_path)
    (tmp_path / "calibration" / "walkrepro.yaml").unlink()
    from walkrepro.specs import calibrated as references

    monkeypatch.setattr(references, "CALIBRATION_DIR", tmp_path / "none")
    with pytest.raises(SpecError, match=r"line 8, field controller.params.kp.*no calibration file"):
        load_spec(path)


def test_a_calibrated_row_must_be_a_criterion(tmp_path: Path) -> None:
    """A row marked calibrated that no parameter targets is refused at its line."""
    spec = SPEC.replace("source: test}", "source: test, calibrated: gain}")
    with pytest.raises(SpecError, match=r"line 11, field expect.0.calibrated.*not a criterion"):
        load_spec(write_tree(tmp_path, spec=spec))


def test_a_row_cannot_be_calibrated_and_a_known_deviation(tmp_path: Path) -> None:
    """`calibrated` and `known_deviation` on one row are refused."""
    spec = SPEC.replace(
        "calibrated: gain}", "calibrated: gain, known_deviation: {reason: r, observed: [0, 1]}}"
    )
    with pytest.raises(SpecError, match=r"line 12.*both calibrated and a known deviation"):
        load_spec(write_tree(tmp_path, spec=spec))


# --------------------------------------------------------------------------------------
# The rules between a calibration file and the specs


def test_a_criterion_that_names_a_checked_claim_is_refused(tmp_path: Path) -> None:
    """A criterion whose row is not marked calibrated is a checked claim: refused."""
    write_tree(tmp_path, spec=SPEC.replace(", calibrated: gain}", "}"))
    with pytest.raises(SpecError, match="criterion names a checked claim") as exc:
        check_consistency(load_calibration(tmp_path / "calibration" / "walkrepro.yaml"))
    assert "walkrepro.yaml, line 10, field parameters.0.metric" in str(exc.value)
    assert "tiny.yaml, line 12" in str(exc.value)


def test_a_criterion_without_a_row_is_refused(tmp_path: Path) -> None:
    """A criterion must be visible as a calibrated row of its experiment."""
    write_tree(
        tmp_path,
        calibration=CALIBRATION.replace('"mean_forward_speed:0.1-0.3"', "mean_forward_speed:0-0.3"),
    )
    with pytest.raises(SpecError, match="a row marked calibrated"):
        check_consistency(load_calibration(tmp_path / "calibration" / "walkrepro.yaml"))


def test_a_set_path_outside_the_controller_params_is_refused(tmp_path: Path) -> None:
    """`set` must name a field of the controller's parameter model."""
    write_tree(
        tmp_path, calibration=CALIBRATION.replace("controller.params.kp", "controller.params.kq")
    )
    with pytest.raises(WalkreproError, match=r"line 5, field parameters.0.set.*'kq'.*kp"):
        check_consistency(load_calibration(tmp_path / "calibration" / "walkrepro.yaml"))


def test_a_consistent_tree_passes(tmp_path: Path) -> None:
    """The test tree keeps every rule (so the refusals above come from their one change)."""
    write_tree(tmp_path)
    check_consistency(load_calibration(tmp_path / "calibration" / "walkrepro.yaml"))


def test_a_bad_calibration_file_names_file_line_and_field(tmp_path: Path) -> None:
    """A schema error in the calibration file cites its line and field, no traceback."""
    write_tree(tmp_path, calibration=CALIBRATION.replace("xtol: 1.0", "xtol: -1.0"))
    with pytest.raises(
        SpecError,
        match=r"walkrepro.yaml, line 12, field parameters.0.search.xtol: .*greater than 0",
    ):
        load_calibration(tmp_path / "calibration" / "walkrepro.yaml")


# (in_place_open_loop: calibrated: stance_ankle_bias / dead_zone_thresholds) and refer to
# {calibrated: stance_ankle_bias}.
@pytest.mark.parametrize("paper", calibration_papers())
def test_shipped_calibrations_are_consistent(paper: str) -> None:
    """Every shipped calibration file keeps the rules with the shipped specs."""
    check_consistency(load_calibration(CALIBRATION_DIR / f"{paper}.yaml"))


def test_shipped_calibration_files_load() -> None:
    """Every shipped calibration file is valid and reads back as written (no comments)."""
    for paper in calibration_papers():
        path = CALIBRATION_DIR / f"{paper}.yaml"
        assert dump_calibration(load_calibration(path).model) == path.read_text()


# --------------------------------------------------------------------------------------
# Searches


def problem(**kw: object) -> RootProblem:
    fields = dict(
        metric=METRIC, target=0.0, tolerance=0.01, bracket=(100.0, 600.0), xtol=1.0, points=2
    )
    fields.update(kw)
    return RootProblem(**fields)  # type: ignore[arg-type]


def fake(xs: list[float]) -> list[dict[str, float]]:
    return [{METRIC: speed_of_gain(x)} for x in xs]


def test_root_search_finds_the_root_within_xtol() -> None:
    """The parallel bisection ends within xtol of the root, at its best evaluated point."""
    found = find_root(problem(), fake)
    assert abs(found.value - 321.0) < 1.0
    best = min(found.evaluations, key=lambda e: abs(e[1]))
    assert (found.value, found.measured) == best
    assert found.evaluations[:4] == tuple(
        (x, speed_of_gain(x)) for x in [100.0, *split(100.0, 600.0, 2), 600.0]
    )


def test_a_calibration_without_a_sign_change_fails() -> None:
    """A bracket over which the residual keeps its sign fails with the two ends' values."""
    with pytest.raises(CalibrationFailed, match="does not change sign"):
        find_root(problem(bracket=(400.0, 600.0)), fake)


def test_a_calibration_that_misses_its_tolerance_fails() -> None:
    """A root the bracket's resolution cannot reach within the tolerance fails."""
    steep = lambda xs: [{METRIC: 10.0 * (x - 321.37)} for x in xs]  # noqa: E731
    with pytest.raises(CalibrationFailed, match="tolerance"):
        find_root(problem(xtol=5.0), steep)


def test_a_run_without_a_value_fails_the_search() -> None:
    """A NaN criterion (a fall, an unmeasurable metric) fails the search."""
    with pytest.raises(CalibrationFailed, match="no value"):
        find_root(problem(), lambda xs: [{METRIC: math.nan} for _ in xs])


def test_root_search_is_deterministic_and_independent_of_jobs(tmp_path: Path) -> None:
    """One job and two give bit-identical results on the engine (points come from the file)."""
    write_tree(tmp_path)
    loaded = load_calibration(tmp_path / "calibration" / "walkrepro.yaml")
    results = []
    for jobs in (1, 2, 2):
        options = CalibrateOptions(jobs=jobs)
        evaluators = EngineEvaluators(loaded, options, ProcessEngine(jobs, fake_cell))
        (run,) = calibrate(loaded, options, evaluators.make)
        results.append(run.result)
    assert results[0].evaluations == results[1].evaluations == results[2].evaluations
    assert results[0].value == results[1].value and abs(results[0].value - 321.0) < 1.0


def test_later_parameters_use_the_earlier_ones_just_found(tmp_path: Path) -> None:
    """A measure after a root search sees the value found now, not the committed one."""
    extra = """\
- name: echo
  set: controller.params.kd
  unit: Nms/rad
  criterion: {kind: identification_procedure, quote: q, section: s}
  experiment: tiny
  metric: fell
  search: {method: measure}
  result: null
"""
    write_tree(tmp_path, calibration=CALIBRATION + extra)
    loaded = load_calibration(tmp_path / "calibration" / "walkrepro.yaml")
    seen = []

    def factory(parameter, context):  # noqa: ANN001, ANN202
        def evaluate(xs):  # noqa: ANN001, ANN202
            seen.append(dict(context))
            return fake(xs) if parameter.name == "gain" else [{"fell": 0.0}]

        return evaluate

    runs = calibrate(loaded, CalibrateOptions(), factory)
    assert [r.parameter.name for r in runs] == ["gain", "echo"]
    assert seen[-1]["gain"] == runs[0].result.value != 321.5
    assert "echo" in seen[0]  # unavailable to the earlier parameter's runs


# --------------------------------------------------------------------------------------
# Counting


def test_calibrated_rows_are_counted_apart(tmp_path: Path) -> None:
    """A calibrated row that holds counts `calibrated`; one that misses fails; JUnit agrees."""
    spec = load_spec(write_tree(tmp_path)).spec
    held = evaluate(spec, {"fell": 0.0, METRIC: 0.001}, "complete")
    missed = evaluate(spec, {"fell": 0.0, METRIC: 0.5}, "complete")
    assert [r.status for r in held.rows][1] == CALIBRATED and held.passed
    assert [r.status for r in missed.rows][1] == FAIL and not missed.passed
    counts = count([held, missed])
    assert (counts.reproduced, counts.calibrated, counts.known, counts.failed) == (2, 1, 0, 1)
    assert str(counts) == "2 reproduced, 1 calibrated, 0 known deviations, 1 failed"
    write_junit([held, missed], tmp_path / "j.xml")
    root = ET.parse(tmp_path / "j.xml").getroot()
    assert (root.get("tests"), root.get("failures"), root.get("calibrated")) == ("4", "1", "1")
    suite = root.find("testsuite")
    assert suite is not None and suite.get("calibrated") == "1"
    marked = suite.findall("testcase/properties/property[@value='calibrated']")
    assert len(marked) == 1


# --------------------------------------------------------------------------------------
# The command


def test_calibrate_command_updates_then_reproduces(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without a result it differs (exit 1); --update writes it; then it reproduces."""
    from walkrepro.cli import app
    from walkrepro.studies.calibration import run as calibration_run

    write_tree(tmp_path, result="null")
    monkeypatch.setattr(calibration_model, "CALIBRATION_DIR", tmp_path / "calibration")
    monkeypatch.setattr(
        calibration_run.EngineEvaluators,
        "run",
        lambda self, parameter, context, xs: fake(list(xs)),
    )
    runner = CliRunner()
    path = tmp_path / "calibration" / "walkrepro.yaml"
    before = path.read_text()
    first = runner.invoke(app, ["calibrate", "walkrepro", "--jobs", "1"])
    assert first.exit_code == 1 and "no committed result" in first.output, first.output
    assert path.read_text() == before
    update = runner.invoke(app, ["calibrate", "walkrepro", "--jobs", "1", "--update"])
    assert update.exit_code == 0, update.output
    written = load_calibration(path).model
    original = load_calibration(path).model.model_copy()
    assert written.parameters[0].criterion == original.parameters[0].criterion
    assert abs(written.parameters[0].result.value - 321.0) < 1.0  # type: ignore[union-attr]
    again = runner.invoke(app, ["calibrate", "walkrepro", "--jobs", "1"])
    assert again.exit_code == 0 and "reproduces the committed calibration" in again.output
    bad = runner.invoke(app, ["calibrate", "nope"])
    assert bad.exit_code == 2 and "walkrepro" in bad.output and "Traceback" not in bad.output


def test_update_keeps_every_authored_field(tmp_path: Path) -> None:
    """Writing results changes only `result`: the authored fields read back unchanged."""
    write_tree(tmp_path, result="null")
    loaded = load_calibration(tmp_path / "calibration" / "walkrepro.yaml")
    committed = load_calibration(
        write_tree(tmp_path / "other").parent / "calibration" / "walkrepro.yaml"
    )
    result = committed.model.parameters[0].result
    assert result is not None
    new = with_results(loaded.model, {"gain": result})
    dumped = new.model_dump(exclude={"parameters": {0: {"result"}}})
    assert dumped == loaded.model.model_dump(exclude={"parameters": {0: {"result"}}})
    assert "points" not in dump_calibration(new)  # a default the author left out stays out
    assert compare(committed, []) == []


def test_a_withheld_reference_takes_the_default(tmp_path: Path) -> None:
    """A value withheld from a criterion run (a later parameter's) is left out: the default."""
    from walkrepro.specs.calibrated import Withheld

    path = write_tree(tmp_path)
    loaded = load_spec(path, calibrated={"gain": Withheld("calibrated later")})
    assert "kp" not in loaded.spec.controller.params  # the controller's default applies


def test_rows_name_the_calibrated_rows_apart_from_the_searched_metrics(tmp_path: Path) -> None:
    """With `rows`, the marked rows are those rows; a row marked for the metric is refused."""
    rows = CALIBRATION.replace("  search:", "  rows: [fell]\n  search:")
    spec = SPEC.replace(", calibrated: gain}", "}").replace(
        "source: test}", "source: test, calibrated: gain}"
    )
    write_tree(tmp_path, spec=spec, calibration=rows)
    calibration = load_calibration(tmp_path / "calibration" / "walkrepro.yaml")
    assert calibration.model.parameters[0].criterion_rows == ("fell",)
    check_consistency(calibration)
    assert load_spec(tmp_path / "tiny.yaml").spec.expect[0].calibrated == "gain"
    write_tree(tmp_path, calibration=rows)  # the speed row marked, not the fell row
    with pytest.raises(SpecError, match="not a criterion"):
        load_spec(tmp_path / "tiny.yaml")


@pytest.mark.repro
@pytest.mark.slow
def test_the_shipped_paper_ii_calibration_reproduces() -> None:
    """``walkrepro calibrate faraji`` re-runs the committed calibration (issue 30, acceptance
    1): the stance bias's root search, μ and the Fig. 9 thresholds, on 2 processes, within the
    relative tolerance references are compared by (another machine's libraries move the last
    digits)."""
    from walkrepro.cli import app

    result = CliRunner().invoke(app, ["calibrate", "faraji", "--jobs", "2"])
    assert result.exit_code == 0, result.output
    assert "reproduces the committed calibration" in result.output


# --------------------------------------------------------------------------------------
# Criterion kinds: a disturbance's description, a result a value was chosen on

CHOSEN = """\
paper: walkrepro
description: a value chosen by looking at a result
parameters:
- name: gain
  set: controller.params.kp
  unit: Nm/rad
  criterion: {kind: result, quote: the robot stands still, section: test}
  experiment: tiny
  metric: "mean_forward_speed:0.1-0.3"
  search: {method: chosen, value: VALUE, how: looked at the sway}
  result: RESULT
"""


def test_a_chosen_value_is_declared_with_the_result_it_was_chosen_on(tmp_path: Path) -> None:
    """A chosen value whose spec runs with it passes the rules; its row counts calibrated."""
    write_tree(tmp_path, calibration=CHOSEN.replace("VALUE", "321.5"))
    check_consistency(load_calibration(tmp_path / "calibration" / "walkrepro.yaml"))


def test_a_chosen_value_that_is_not_the_model_in_force_is_refused(tmp_path: Path) -> None:
    """A declaration whose chosen value differs from the spec's value fails rule 5."""
    spec = SPEC.replace("kp: {calibrated: gain}", "kp: 250.0")
    write_tree(tmp_path, spec=spec, calibration=CHOSEN.replace("VALUE", "321.5"))
    with pytest.raises(SpecError, match=r"chosen value 321.5 is not the one tiny runs with"):
        check_consistency(load_calibration(tmp_path / "calibration" / "walkrepro.yaml"))


@pytest.mark.parametrize(
    ("criterion", "search", "message"),
    [
        ("result", "{method: measure}", "chosen"),
        ("setup_statement", "{method: chosen, value: 1.0, how: x}", "chosen"),
        ("disturbance_description", "{method: measure}", "disturbance"),
    ],
)
def test_criterion_kinds_keep_to_their_searches_and_targets(
    tmp_path: Path, criterion: str, search: str, message: str
) -> None:
    """Only a result criterion has a chosen value, and a disturbance's description may set
    only that disturbance (never a controller gain)."""
    text = (
        CHOSEN.replace("kind: result", f"kind: {criterion}")
        .replace("{method: chosen, value: VALUE, how: looked at the sway}", search)
        .replace("RESULT", "null")
    )
    path = tmp_path / "calibration" / "walkrepro.yaml"
    path.parent.mkdir(parents=True)
    path.write_text(text)
    with pytest.raises(SpecError, match=message):
        load_calibration(path)


def test_a_calibration_reproduces_within_its_tolerance_only() -> None:
    """A last-digit move (another machine's libraries) reproduces; 1e-5 relative does not."""
    from walkrepro.specs.calibration_files import close_value

    assert close_value(0.0506, 0.0506 * (1 + 1e-12))
    assert close_value((0.0084, 0.0043), (0.0084 * (1 + 1e-9), 0.0043))
    assert not close_value(0.0506, 0.0506 * (1 + 1e-5))
    assert not close_value((0.0084, 0.0043), (0.0084,))
    assert not close_value(float("nan"), float("nan"))
    assert close_value("option_a", "option_a") and not close_value("option_a", "option_b")
