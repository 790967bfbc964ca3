"""One notion of a damaged log: a real log cut short is named as cut (what it holds, what is
missing) by every reader, which exits non-zero, unless --partial, when every output says
partial."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

import walkrepro
from walkrepro.cli import app
from walkrepro.errors import WalkreproError
from walkrepro.log import record
from walkrepro.log.integrity import DamagedLogError, integrity, read_checked_log
from walkrepro.runtime import gl

runner = CliRunner()
DURATION = 1.0  # [s] simulated: a log of ≈ 1 MB in several chunks


def _invoke(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete stand_coman run directory of 1 s."""
    root = tmp_path_factory.mktemp("integrity") / "runs"
    args = ["run", "stand_coman", "--set", f"sim.duration={DURATION}", "--out", str(root)]
    code, text = _invoke(*args, "--no-figures")
    assert code == 0, text
    (directory,) = (root / "stand_coman").iterdir()
    return directory


@pytest.fixture
def cut(whole: Path, tmp_path: Path) -> Path:
    """A copy of the run whose log is cut to half its bytes (a copy that stopped)."""
    directory = tmp_path / "cut_run"
    shutil.copytree(whole, directory)
    log = directory / "log.mcap"
    with log.open("r+b") as f:
        f.truncate(log.stat().st_size // 2)
    return directory


def test_a_whole_log_is_whole(whole: Path) -> None:
    """The run's own log reads to its footer: nothing to say."""
    log, found = read_checked_log(whole / "log.mcap")
    assert found.whole and found.describe() == "" and found.short() == ""
    assert found.held == pytest.approx(DURATION, abs=0.01)


def test_a_cut_log_is_named_with_what_it_holds_and_lacks(cut: Path) -> None:
    """Cut in half, the log holds part of the run: the message says how much of how much,
    and that the summary and footer are missing."""
    log = record.read_log(cut / "log.mcap")
    found = integrity(log)
    assert not found.whole and found.cut
    assert 0.1 < found.held < DURATION and found.expected == pytest.approx(DURATION)
    text = found.describe()
    assert text.startswith(f"log cut: holds {found.held:.3g} s of 1 s (run.json)")
    assert "missing its summary and footer" in text
    with pytest.raises(DamagedLogError, match="log cut: holds .* --partial"):
        read_checked_log(cut / "log.mcap")


def test_check_run_names_the_cut_and_exits_1_unless_partial(cut: Path) -> None:
    """`check --run` on a cut log: exit 1, the cut named; with --partial the verdict's
    outcome is partial (never a pass) and check.json says so."""
    import json

    code, text = _invoke("check", "--run", str(cut))
    assert code == 1 and "log cut: holds" in text and "--partial" in text
    code, text = _invoke("check", "--run", str(cut), "--partial")
    assert code == 1 and "partial" in text and "run: outcome partial" in text
    assert json.loads((cut / "check.json").read_text())["outcome"] == "partial"


def test_the_python_api_refuses_a_cut_log_and_a_wrong_argument(cut: Path) -> None:
    """walkrepro.evaluate: a cut log raises DamagedLogError unless partial=True (outcome
    partial, the cut is each unmeasurable row's reason); a number is a WalkreproError that
    says what to give, not a TypeError."""
    with pytest.raises(DamagedLogError, match="log cut"):
        walkrepro.evaluate(cut)
    verdict = walkrepro.evaluate(cut, partial=True)
    assert verdict.outcome == "partial" and not verdict.passed
    assert any("log cut" in r.note for r in verdict.rows if math.isnan(r.measured))
    with pytest.raises(WalkreproError, match="give a run .*not a int") as raised:
        walkrepro.evaluate(42)  # type: ignore[arg-type]
    assert not isinstance(raised.value, TypeError)


def test_plot_refuses_a_cut_log_and_titles_partial_figures(cut: Path, tmp_path: Path) -> None:
    """`plot` on a cut log: exit 1; with --partial every figure's title says PARTIAL."""
    code, text = _invoke("plot", str(cut), "--out", str(tmp_path / "figs"))
    assert code == 1 and "log cut" in text
    code, text = _invoke("plot", str(cut), "--out", str(tmp_path / "figs"), "--partial")
    assert code == 0, text
    svgs = list((tmp_path / "figs").glob("*.svg"))
    assert svgs and all("PARTIAL" in svg.read_text() for svg in svgs)


def test_export_refuses_a_cut_log_and_a_partial_recording_says_so(
    cut: Path, tmp_path: Path
) -> None:
    """`export --rerun` on a cut log: exit 1; with --partial the recording's verdict panel
    says PARTIAL and what the log holds, not the run's earlier verdict."""
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    out = tmp_path / "cut.rrd"
    code, text = _invoke("export", str(cut), "--rerun", "--out", str(out))
    assert code == 1 and "log cut" in text and not out.exists()
    code, text = _invoke("export", str(cut), "--rerun", "--out", str(out), "--partial")
    assert code == 0, text
    texts = []
    for chunk in RrdReader(out).store().stream():
        if chunk.entity_path == "/verdict":
            batch = chunk.to_record_batch()
            texts += [str(v) for v in batch.column("TextDocument:text").to_pylist()]
    assert texts and all("PARTIAL" in t and "log cut" in t for t in texts)
    assert not any("passed" in t for t in texts)


@pytest.mark.skipif(not gl.available(), reason="no OpenGL backend")
def test_render_refuses_a_cut_log_unless_partial(cut: Path, tmp_path: Path) -> None:
    """`render` (strip and video) on a cut log: exit 1; with --partial it renders what the
    log holds."""
    strip = tmp_path / "strip.png"
    code, text = _invoke("render", str(cut), "--at", "0,0.2", "--out", str(strip))
    assert code == 1 and "log cut" in text and not strip.exists()
    code, text = _invoke("render", str(cut), "--at", "0,0.2", "--out", str(strip), "--partial")
    assert code == 0 and strip.is_file(), text
    video = tmp_path / "v.mp4"
    code, text = _invoke("render", str(cut), "--video", "--out", str(video))
    assert code == 1 and "log cut" in text and not video.exists()
