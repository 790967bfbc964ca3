"""Reproduction checks: every shipped experiment runs in physics and meets its paper's expectations.

These run the real experiments (marker ``repro``); CI runs them on every change.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.log import record
from walkrepro.runs.results import latest_run
from walkrepro.runtime import gl
from walkrepro.sim.replay import verify_log
from walkrepro.specs.files import experiment_names

runner = CliRunner()


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str]:
    """Run `walkrepro check` over every shipped experiment once, in parallel."""
    out = tmp_path_factory.mktemp("runs")
    junit = out / "junit.xml"
    result = runner.invoke(
        app,
        [
            "check",
            *experiment_names(),
            "--out",
            str(out),
            "--jobs",
            "2",
            "--junit",
            str(junit),
            "--figures",
        ],
    )
    return out, result.exit_code, result.output


@pytest.mark.repro
def test_every_experiment_meets_its_expectations(checked: tuple[Path, int, str]) -> None:
    """`walkrepro check` over all experiments exits 0: every paper expectation holds or is a declared deviation."""
    _, code, output = checked
    assert code == 0, output
    summary = re.findall(
        r"\d+ reproduced, \d+ calibrated, \d+ known deviations?, \d+ failed", output
    )[-1]
    assert summary.endswith(" 0 failed"), output
    assert "all expectations hold" not in output


@pytest.mark.repro
def test_junit_counts_match_the_summary(checked: tuple[Path, int, str]) -> None:
    """The JUnit file counts the same known deviations (skipped) and failures as the summary line."""
    out, _, output = checked
    # The last count line is the batch's summary (each experiment's progress line has one too).
    summary = re.findall(
        r"(\d+) reproduced, (\d+) calibrated, (\d+) known deviations?, (\d+) failed", output
    )[-1]
    reproduced, calibrated, known, failed = map(int, summary)
    root = ET.parse(out / "junit.xml").getroot()
    assert int(root.get("tests")) == reproduced + calibrated + known + failed
    assert (int(root.get("skipped")), int(root.get("failures"))) == (known, failed)
    assert int(root.get("calibrated")) == calibrated


@pytest.mark.repro
@pytest.mark.parametrize("name", experiment_names())
def test_every_log_replays_bit_exactly(checked: tuple[Path, int, str], name: str) -> None:
    """Each experiment's log re-simulates from its own scene and inputs within 1e-9."""
    out, _, _ = checked
    run = latest_run(out, name)
    assert run is not None, f"no run directory for {name}"
    report = verify_log(run / "log.mcap")
    assert report.ok and report.n_states_compared > 10, report
    assert (run / "figures" / "overview.png").is_file()


@pytest.mark.repro
@pytest.mark.skipif(not gl.available(), reason=gl.INSTALL_HINT.format(tried="probed at collection"))
def test_render_shows_the_robot(checked: tuple[Path, int, str]) -> None:
    """`walkrepro render` writes a snapshot strip in which the robot is visible (not a blank image)."""
    out, _, _ = checked
    run = latest_run(out, "stand_dyros_red")
    assert run is not None
    png = run / "figures" / "snapshots.png"
    result = runner.invoke(app, ["render", str(run), "--at", "0,2,4", "--out", str(png)])
    assert result.exit_code == 0, result.output
    image = mpimg.imread(png)
    assert image.shape[1] > image.shape[0]  # a horizontal strip
    # The robot's red links must be present: many pixels far redder than the grey floor.
    red = (image[..., 0] > 0.45) & (image[..., 0] > 1.6 * image[..., 1])
    assert red.sum() > 500, f"only {red.sum()} red pixels: the robot is not in the picture"


@pytest.mark.repro
def test_standing_logs_have_no_external_forces(checked: tuple[Path, int, str]) -> None:
    """A standing run applies no disturbance: every logged xfrc is empty (no hidden helper forces)."""
    out, _, _ = checked
    for name in ("stand_dyros_red", "stand_coman", "stand_kist_humanoid"):
        run = latest_run(out, name)
        assert run is not None
        inputs = record.read_log(run / "log.mcap").messages(record.TOPIC_INPUTS)
        assert inputs and all(m["xfrc"] == {} for m in inputs)
        assert np.isfinite([c for m in inputs[:10] for c in m["ctrl"]]).all()


@pytest.mark.repro
@pytest.mark.slow
def test_ablation_with_epsilon_back_on_fails(tmp_path: Path) -> None:
    """forward_walk_no_epsilon with ε switched back on (partner run paired with the same override) fails its check."""
    result = runner.invoke(
        app,
        [
            "check",
            "forward_walk_no_epsilon",
            "--set",
            "controller.params.use_epsilon=true",
            "--out",
            str(tmp_path),
        ],
    )
    assert result.exit_code == 1, result.output
    assert "forward_walk:" in result.output  # the partner ran in the same batch
    assert "this batch" in result.output
