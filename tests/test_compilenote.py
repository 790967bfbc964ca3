"""The first run says what it does: the compile note, the cold-cache check, the watch."""

from __future__ import annotations

import io
from pathlib import Path

import numba
import pytest
from rich.console import Console
from typer.testing import CliRunner

from walkrepro import plugins
from walkrepro.cli import app
from walkrepro.runtime import compilenote

#: Paper I's controller class, as the plugin registry names it.
EFSM = plugins.controllers()["efsm"]

SPEC = """\
name: tiny_stand
description: a short standing run
paper: {key: walkrepro}
robot: dyros_red
controller: {type: posture}
sim: {timestep: 0.0005, control_period: 0.001, duration: 0.05}
expect:
  - {metric: fell, op: "==", value: 0, source: test}
"""


def test_the_note_names_the_paper_and_the_measured_time() -> None:
    """The note names the paper's controller and the measured cold compile, in minutes when
    long."""
    assert compilenote.note("efsm", "Paper I") == (
        "compiling the Paper I controller (efsm), once per machine: ~2 min"
    )
    assert compilenote.note("posture", None) == (
        "compiling the posture controller, once per machine: ~10 s"
    )
    assert compilenote.note("mine", None) == "compiling the mine controller, once per machine"


def test_kernel_files_are_the_papers_own_or_the_simulators() -> None:
    """Paper I's kernels are its package's numba modules; Paper II's controller has none of
    its own, so the simulator's kernels stand for its compile."""
    lee = {f.name for f in compilenote.kernel_files(EFSM)}
    assert {"kernels.py", "wbc.py", "fsm.py"} <= lee
    shared = compilenote.kernel_files(plugins.controllers()["timeprojection"])
    assert shared and all(f.parent.name == "sim" for f in shared)
    assert compilenote.kernel_files("walkrepro.no_such_module:X") == []


def test_a_cache_is_cold_until_it_holds_an_index_of_the_kernels(tmp_path: Path) -> None:
    """An empty cache directory is cold; one index of one of the paper's kernel modules, in
    numba's folder layout, makes it warm."""
    assert compilenote.is_cold(EFSM, tmp_path)
    other = tmp_path / "faraji_0123abcd"
    other.mkdir()
    (other / "controller.step-10.py311.nbi").write_bytes(b"")
    assert compilenote.is_cold(EFSM, tmp_path)
    folder = tmp_path / "lee2021_0123abcd"
    folder.mkdir()
    (folder / "kernels.tick-100.py311.nbi").write_bytes(b"")
    assert not compilenote.is_cold(EFSM, tmp_path)


def test_run_prints_the_note_first_when_the_cache_is_cold(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With a cold cache, ``walkrepro run`` prints the note before anything of the run, and
    the run then completes."""
    monkeypatch.setattr(compilenote, "is_cold", lambda controller, directory=None: True)
    path = tmp_path / "tiny.yaml"
    path.write_text(SPEC)
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    note = "compiling the posture controller, once per machine"
    assert note in result.output
    assert result.output.index(note) < result.output.index("reproduced")


def test_run_is_silent_about_compiling_on_a_warm_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With a warm cache (and nothing left to compile), the run says nothing of compiling."""
    monkeypatch.setattr(compilenote, "is_cold", lambda controller, directory=None: False)
    path = tmp_path / "tiny.yaml"
    path.write_text(SPEC)
    runs = str(tmp_path / "runs")
    CliRunner().invoke(app, ["run", str(path), "--out", runs])  # compiles what is missing
    result = CliRunner().invoke(app, ["run", str(path), "--out", runs])
    assert result.exit_code == 0, result.output
    assert "compiling" not in result.output


def test_the_watch_says_so_when_numba_compiles_unforeseen() -> None:
    """A compile the cold check did not foresee still prints the note, counts the function
    and ends with what was compiled."""

    @numba.njit(cache=False)
    def double(x: float) -> float:
        return 2.0 * x

    console = Console(file=io.StringIO(), width=100, color_system=None)
    with compilenote.CompileWatch(console, None, "compiling the test controller") as watch:
        assert double(1.5) == 3.0
        assert watch.compiling
    text = console.file.getvalue()
    assert "compiling the test controller" in text
    assert "compiled 1 function in " in text


def test_the_watch_hands_its_progress_to_a_bar() -> None:
    """After :meth:`hand_over`, the compile's progress goes to the given update function,
    and :meth:`finish` returns the summary for the bar's console."""

    @numba.njit(cache=False)
    def triple(x: float) -> float:
        return 3.0 * x

    shown: list[str] = []
    console = Console(file=io.StringIO(), width=100, color_system=None)
    watch = compilenote.CompileWatch(console, "compiling now", "unused")
    with watch:
        watch.hand_over(shown.append)
        watch.REFRESH = 0.0
        assert triple(1.0) == 3.0
        summary = watch.finish()
    assert shown and all(s.startswith("compiling ") for s in shown)
    assert summary is not None and summary.startswith("compiled ")
    assert "compiling now" in console.file.getvalue()
