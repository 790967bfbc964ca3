"""A run's record is true after any stop: each post-simulation stage (metrics, figures,
video) records in run.json that it completed, was interrupted or failed; the terminal says
which; `check --run` and the report show what is missing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.runs import experiment, results

runner = CliRunner()
STAND = ["stand_coman", "--set", "sim.duration=0.1"]


def _only_run(root: Path) -> Path:
    (directory,) = (root / "stand_coman").iterdir()
    return directory


def test_ctrl_c_in_the_video_is_recorded_said_and_exits_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C while the video renders: exit 130, the terminal names the video stage and the
    missing video.mp4, run.json records metrics and figures completed and the video
    interrupted; `check --run` and the report show the missing video."""
    seen: dict = {}

    def interrupted_video(log_path: Path, work: Path, flag: object) -> str:
        seen.update(json.loads((work / results.RUN_FILE).read_text())["stages"])
        raise KeyboardInterrupt

    monkeypatch.setattr(experiment, "_render_video", interrupted_video)
    out = tmp_path / "runs"
    result = runner.invoke(app, ["run", *STAND, "--out", str(out)])
    assert result.exit_code == 130, result.output
    assert "Traceback" not in result.output
    assert "interrupted (SIGINT) during the video stage" in result.output
    assert "missing: video.mp4 (the video stage was interrupted)" in result.output
    assert seen["video"] == results.STARTED  # a kill here would have left "started"
    run_dir = _only_run(out)
    record = json.loads((run_dir / results.RUN_FILE).read_text())
    assert record["stages"] == {
        "metrics": results.COMPLETED,
        "figures": results.COMPLETED,
        "video": results.INTERRUPTED,
    }
    assert not (run_dir / "video.mp4").exists()
    assert not [p for p in run_dir.iterdir() if "partial" in p.name]

    checked = runner.invoke(app, ["check", "--run", str(run_dir)])
    assert checked.exit_code == 0, checked.output
    assert "missing: video.mp4 (the video stage was interrupted)" in checked.output

    from walkrepro.publish.report import build_report

    site = build_report(out, tmp_path / "site")
    page = next(p for p in site.pages if p.name != "index.html" and "robots" not in p.parts)
    assert "missing: video.mp4 (the video stage was interrupted)" in page.read_text()


def test_a_failing_figure_stage_is_recorded_as_failed_and_the_video_skipped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An exception while drawing the figures: run.json says figures failed and the video
    was skipped (never run), with the error; the command shows the error, not a run that
    completed."""

    def broken(log_path: Path, work: Path, flag: object) -> str:
        raise RuntimeError("matplotlib broke")

    monkeypatch.setattr(experiment, "_draw_figures", broken)
    out = tmp_path / "runs"
    result = runner.invoke(app, ["run", *STAND, "--out", str(out)])
    assert result.exit_code != 0
    record = json.loads((_only_run(out) / results.RUN_FILE).read_text())
    assert record["outcome"] == "error" and "matplotlib broke" in record["message"]
    assert record["stages"] == {
        "metrics": results.COMPLETED,
        "figures": results.FAILED,
        "video": results.SKIPPED,
    }


def test_missing_outputs_read_the_stages() -> None:
    """Completed and unrequested stages are not missing; every other status is, said."""
    stages = {
        "metrics": results.COMPLETED,
        "figures": results.NOT_REQUESTED,
        "video": results.UNAVAILABLE,
    }
    assert results.missing_outputs({"stages": stages}) == [
        "video.mp4 (the video stage could not run: no OpenGL backend)"
    ]
    assert results.missing_outputs({}) == []  # a run recorded before stages were
