"""Tests of `walkrepro sweep` and `walkrepro plot SWEEP_DIR` end to end (short stand runs)."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.studies.sweep import store

runner = CliRunner()
GRID = ["--grid", "sim.duration=0.1,0.15", "--grid", "controller.params.kp=300,400"]


def _sweep_dirs(out: Path) -> list[Path]:
    return sorted((out / "sweeps" / "stand_dyros_red").glob("*/"))


def _rows(directory: Path) -> list[dict]:
    with (directory / store.CELLS_FILE).open() as f:
        return list(csv.DictReader(f))


def test_sweep_writes_cells_and_a_map_and_resume_runs_nothing(tmp_path: Path) -> None:
    """A 2×2 sweep writes sweep.yaml, a 4-row cells.csv and map.png; --resume keeps 4 rows."""
    result = runner.invoke(
        app, ["sweep", "stand_dyros_red", *GRID, "--jobs", "2", "--out", str(tmp_path)]
    )
    assert result.exit_code == 0, result.output
    (directory,) = _sweep_dirs(tmp_path)
    rows = _rows(directory)
    assert len(rows) == 4 and {r["outcome"] for r in rows} == {"complete"}
    assert {
        "cell",
        "sim.duration",
        "controller.params.kp",
        "fall_time",
        "pelvis_drift",
        "passed",
        "wall_time",
    } <= rows[0].keys()
    assert (directory / "map.png").stat().st_size > 0 and (directory / "map.svg").is_file()
    assert not (directory / "cells").exists() and not (directory / ".cells").exists()
    info = store.read_info(directory)
    assert info["grid"][0] == {"field": "sim.duration", "values": [0.1, 0.15], "unit": "s"}
    assert info["provenance"]["versions"]["mujoco"] == mujoco.__version__

    again = runner.invoke(app, ["sweep", "--resume", str(directory)])
    assert again.exit_code == 0, again.output
    assert "4 cells, 0 to run" in again.output
    assert _rows(directory) == rows

    (directory / "map.png").unlink()
    plotted = runner.invoke(app, ["plot", str(directory)])
    assert plotted.exit_code == 0 and (directory / "map.png").is_file()


def test_resume_runs_only_missing_cells_and_keep_logs_keeps_runs(tmp_path: Path) -> None:
    """Rows removed from cells.csv are run again by --resume; --keep-logs keeps each cell's run."""
    args = ["sweep", "stand_dyros_red", "--grid", "sim.duration=0.1,0.15", "--jobs", "1"]
    assert runner.invoke(app, [*args, "--out", str(tmp_path), "--keep-logs"]).exit_code == 0
    (directory,) = _sweep_dirs(tmp_path)
    assert len(list((directory / "cells").glob("*/stand_dyros_red/*/log.mcap"))) == 2
    lines = (directory / store.CELLS_FILE).read_text().splitlines()
    (directory / store.CELLS_FILE).write_text(
        "\n".join(lines[:2]) + "\n" + lines[2][:10]
    )  # a torn row
    result = runner.invoke(app, ["sweep", "--resume", str(directory), "--jobs", "1"])
    assert result.exit_code == 0, result.output
    assert "2 cells, 1 to run" in result.output
    assert sorted(r["cell"] for r in _rows(directory)) == ["0", "1"]


@pytest.mark.parametrize(
    ("grid", "words"),
    [
        ("controller.params.kpp=300,400", "unknown field"),
        ("sim.duration=0.1,abc", "valid number"),
        ("sim.duration=1:2", "bad range"),
    ],
)
def test_bad_grid_is_one_paragraph_exit_2_and_nothing_runs(
    tmp_path: Path, grid: str, words: str
) -> None:
    """A bad field, value or range prints one error paragraph, exits 2 and writes no sweep."""
    result = runner.invoke(
        app, ["sweep", "stand_dyros_red", "--grid", grid, "--out", str(tmp_path)]
    )
    assert result.exit_code == 2
    assert words in result.output and "Traceback" not in result.output
    assert result.output.strip().startswith("error:") and result.output.count("error:") == 1
    assert not (tmp_path / "sweeps").exists()


@pytest.mark.slow
@pytest.mark.parametrize(("signum", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_keeps_finished_cells_and_resume_completes(
    tmp_path: Path, signum: int, code: int
) -> None:
    """SIGINT (or SIGTERM) during a sweep exits 130 (143) with every finished cell kept, even
    in a process that inherited SIGINT ignored; --resume runs the rest."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    # Cells of 2 s simulated: after the first row the other seven take seconds, so the
    # SIGINT below reaches the sweep mid-way even on a loaded machine (0.3 s cells did not).
    grid = "sim.duration=2.0,2.01,2.02,2.03,2.04,2.05,2.06,2.07"
    cmd = [sys.executable, "-m", "walkrepro", "sweep", "stand_dyros_red", "--grid", grid]
    proc = subprocess.Popen(
        [*cmd, "--jobs", "1", "--out", str(tmp_path)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        # Started as a background job of a script is: SIGINT inherited ignored. The sweep
        # must still stop on it (it once ran every cell and exited 0 there).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    # A fresh checkout compiles the kernels first (a minute or more on a loaded machine).
    deadline = time.monotonic() + 900
    while time.monotonic() < deadline and proc.poll() is None:
        dirs = _sweep_dirs(tmp_path)
        if dirs and (dirs[0] / "cells.csv").is_file() and len(_rows(dirs[0])) >= 1:
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep ended before it could be interrupted"
    proc.send_signal(signum)
    output = proc.communicate(timeout=60)[0].decode()
    assert proc.returncode == code, output
    assert "interrupted" in output
    (directory,) = _sweep_dirs(tmp_path)
    kept = _rows(directory)
    assert 1 <= len(kept) < 8
    resumed = subprocess.run(
        [sys.executable, "-m", "walkrepro", "sweep", "--resume", str(directory), "--jobs", "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    rows = _rows(directory)
    assert sorted(int(r["cell"]) for r in rows) == list(range(8))
    assert rows[: len(kept)] == kept  # finished cells are never re-run or rewritten


def test_a_killed_worker_fails_the_sweep_and_resume_runs_its_cell(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A cell whose worker is killed (SIGKILL) is recorded crashed and the sweep exits 1; --resume runs that cell again and completes the sweep."""
    import walkrepro.runs.experiment

    execute = walkrepro.runs.experiment.execute

    def killed_on_the_second_cell(spec, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        if spec.sim.duration == 0.15:  # the worker (forked from this process) dies here
            os.kill(os.getpid(), signal.SIGKILL)
        return execute(spec, *args, **kwargs)

    monkeypatch.setattr(walkrepro.runs.experiment, "execute", killed_on_the_second_cell)
    args = ["sweep", "stand_dyros_red", "--grid", "sim.duration=0.1,0.15", "--jobs", "1"]
    result = runner.invoke(app, [*args, "--out", str(tmp_path)])
    assert result.exit_code == 1, result.output
    assert "1 cell(s) crashed" in result.output and "--resume" in result.output
    (directory,) = _sweep_dirs(tmp_path)
    assert {r["cell"]: r["outcome"] for r in _rows(directory)} == {"0": "complete", "1": "crashed"}

    monkeypatch.undo()
    again = runner.invoke(app, ["sweep", "--resume", str(directory), "--jobs", "1"])
    assert again.exit_code == 0, again.output
    assert "2 cells, 1 to run" in again.output
    rows = _rows(directory)
    assert sorted((r["cell"], r["outcome"]) for r in rows) == [("0", "complete"), ("1", "complete")]


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (("sweep.yaml", "- 0.15", "- 0.2"), "sim.duration was [0.1, 0.15] and is now [0.1, 0.2]"),
        (("sweep.yaml", "- 300", "- 350"), "controller.params.kp was [300, 400]"),
        (("base.yaml", "description:", "description: edited"), "base.yaml was edited"),
        (None, ""),
    ],
    ids=["duration values", "kp values", "base.yaml", "unchanged"],
)
def test_resume_refuses_a_sweep_whose_grid_was_edited(
    tmp_path: Path, edit: tuple[str, str, str] | None, words: str
) -> None:
    """--resume of a sweep whose sweep.yaml values or base.yaml changed since it started is refused in one paragraph (exit 2); an unedited one resumes."""
    from walkrepro.studies.sweep.sweeper import plan_new

    axes = ["sim.duration=0.1,0.15", "controller.params.kp=300,400"]
    plan = plan_new("stand_dyros_red", axes, [], tmp_path)  # planned, nothing run
    if edit is not None:
        name, old, new = edit
        path = plan.directory / name
        assert old in path.read_text()
        path.write_text(path.read_text().replace(old, new, 1))
    result = runner.invoke(app, ["sweep", "--resume", str(plan.directory), "--jobs", "1"])
    if edit is None:
        assert result.exit_code == 0, result.output
        assert "4 cells, 4 to run" in result.output
        return
    assert result.exit_code == 2, result.output
    assert words in result.output and "no longer matches" in result.output, result.output
    assert "Traceback" not in result.output and result.output.count("error:") == 1
    assert _rows(plan.directory) == []
