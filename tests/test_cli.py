"""The command line as a user meets it: friendly errors, run directories, verify, render."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.log import record

runner = CliRunner()

SPEC = """\
name: tiny_stand
description: a short standing run
paper: {key: walkrepro}
robot: dyros_red
controller: {type: posture}
sim: {timestep: 0.0005, control_period: 0.001, duration: 0.3}
expect:
  - {metric: fell, op: "==", value: 0, source: test}
"""


def invoke(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    return result.exit_code, result.output


def assert_friendly(code: int, output: str, *needles: str) -> None:
    assert code == 2, output
    assert "Traceback" not in output
    for needle in needles:
        assert needle in output, output


def test_list_shows_every_experiment_with_its_paper() -> None:
    """`walkrepro list` shows each experiment with its paper key; --long adds the robot and
    the controller."""
    code, out = invoke("list")
    assert code == 0
    for name in ("stand_dyros_red", "stand_coman", "stand_kist_humanoid"):
        assert name in out
    assert "walkrepro" in out
    code, out = invoke("list", "--long")
    assert code == 0 and "posture" in out and "kist_humanoid" in out


def _list_rows() -> list:
    from walkrepro.cli.listing import ListRow
    from walkrepro.specs.files import all_experiment_names, load_spec

    return [ListRow.of(name, load_spec(name).spec) for name in all_experiment_names()]


def test_list_piped_is_one_line_per_experiment() -> None:
    """Piped (not a terminal), `walkrepro list` prints one line per experiment, starting with
    its name, then its paper and figures; --long too, with the robot and controller."""
    from walkrepro.specs.files import all_experiment_names

    names = all_experiment_names()
    for args in (("list",), ("list", "--long")):
        code, out = invoke(*args)
        lines = out.splitlines()
        assert code == 0 and len(lines) == len(names), out
        for name, line in zip(names, lines, strict=True):
            assert line.split()[0] == name, line
    lines = invoke("list")[1].splitlines()
    forward = next(line for line in lines if line.startswith("forward_walk "))
    assert "lee2021" in forward and "6, 7, 8, 15" in forward
    assert max(len(line) for line in lines) <= 40 + 10 + 13 + 100 + 2


def test_list_fits_80_columns_on_a_terminal() -> None:
    """At 80 columns the table shows every name, paper and figure whole, and no line is
    wider than the terminal."""
    import io

    from rich.console import Console

    from walkrepro.cli.listing import experiments_long, experiments_table

    rows = _list_rows()
    for width in (80, 120):
        console = Console(width=width, file=io.StringIO(), color_system=None)
        console.print(experiments_table(rows, width))
        lines = console.file.getvalue().splitlines()
        assert len(lines) == len(rows) + 1  # the header, then one line per experiment
        assert all(len(line.rstrip()) <= width for line in lines)
        for row, line in zip(rows, lines[1:], strict=True):
            assert line.split()[:2] == [row.name, row.paper], line
            assert row.figure in line
    console = Console(width=80, file=io.StringIO(), color_system=None)
    console.print(*experiments_long(rows), sep="\n")
    text = console.file.getvalue()
    assert all(len(line.rstrip()) <= 80 for line in text.splitlines())
    assert "forward_walk  lee2021 · fig. 6, 7, 8, 15 · dyros_red · efsm" in text


@pytest.mark.parametrize(
    ("edit", "needles"),
    [
        (("duration: 0.3", "duration: [0.3"), ("YAML syntax error", "line 6")),
        (("duration: 0.3", "durtion: 0.3"), ("sim.durtion", "unknown field")),
        (("duration: 0.3", "duration: soon"), ("sim.duration", "'soon'")),
        (("duration: 0.3", "duration: -0.3"), ("sim.duration", "greater than 0")),
        (("control_period: 0.001", "control_period: 0.0012"), ("sim.control_period", "multiple")),
        (("robot: dyros_red", "robot: nao"), ("unknown robot 'nao'", "kist_humanoid")),
        (("metric: fell", "metric: falls"), ("unknown metric 'falls'", "footsteps")),
    ],
)
def test_bad_spec_gives_one_paragraph_and_exit_2(
    tmp_path: Path, edit: tuple[str, str], needles: tuple[str, ...]
) -> None:
    """Each kind of bad spec gives exit code 2, no traceback, and names file and field."""
    path = tmp_path / "bad.yaml"
    path.write_text(SPEC.replace(*edit))
    code, out = invoke("run", str(path), "--out", str(tmp_path / "runs"))
    assert_friendly(code, out, "bad.yaml", *needles)
    assert not (tmp_path / "runs").exists(), "a rejected spec must not create a run directory"


def test_unknown_body_and_missing_file(tmp_path: Path) -> None:
    """An unknown disturbance body lists bodies; a missing spec file is named."""
    path = tmp_path / "bad.yaml"
    path.write_text(
        SPEC
        + "disturbances:\n  - {name: p, body: head, force: [1, 0, 0], start: 0, duration: 0.1}\n"
    )
    assert_friendly(*invoke("run", str(path)), "unknown body 'head'", "pelvis")
    assert_friendly(
        *invoke("run", str(tmp_path / "missing.yaml")), "missing.yaml", "no such spec file"
    )
    assert_friendly(*invoke("run", "no_such_experiment"), "unknown experiment", "stand_coman")


def test_unwritable_output_directory(tmp_path: Path) -> None:
    """An output root that cannot be created is reported before anything runs."""
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    path = tmp_path / "ok.yaml"
    path.write_text(SPEC)
    assert_friendly(
        *invoke("run", str(path), "--out", str(blocker / "runs")),
        "cannot write here",
        "--out",
    )


def log_mujoco_version(run: Path) -> str:
    """The MuJoCo version the run's log records in its metadata."""
    return record.read_log(run / "log.mcap").metadata["mujoco_version"]


def test_run_writes_a_complete_run_directory(tmp_path: Path) -> None:
    """A run creates a new directory with spec, log, metrics, verdict and figures; runs never collide."""
    path = tmp_path / "ok.yaml"
    path.write_text(SPEC)
    out = tmp_path / "runs"
    for _ in range(2):
        code, text = invoke("run", str(path), "--out", str(out))
        assert code == 0, text
    runs = sorted((out / "tiny_stand").iterdir())
    assert len(runs) == 2 and not any(r.name.startswith(".") for r in runs)
    run = runs[0]
    for name in (
        "spec.yaml",
        "log.mcap",
        "metrics.json",
        "check.json",
        "run.json",
        "figures/overview.png",
    ):
        assert (run / name).is_file(), name
    assert json.loads((run / "check.json").read_text())["passed"] is True
    # run.json says what made the numbers: the commit and the libraries' versions.
    made_by = json.loads((run / "run.json").read_text())
    assert made_by["commit"] and set(made_by["versions"]) == {
        "python",
        "mujoco",
        "pinocchio",
        "numpy",
        "numba",
    }
    assert made_by["versions"]["mujoco"] == log_mujoco_version(run)
    log = record.read_log(run / "log.mcap")
    assert log.metadata["outcome"] == "complete" and log.metadata["experiment"] == "tiny_stand"
    assert "<mujoco" in log.scene_xml and "tiny_stand" in log.spec_yaml

    code, text = invoke("verify", str(run))
    assert code == 0 and "OK" in text, text
    code, text = invoke("check", "--run", str(run))
    assert code == 0, text
    (run / "figures" / "overview.png").unlink()
    code, text = invoke("plot", str(run))
    assert code == 0 and (run / "figures" / "overview.png").is_file(), text
    code, text = invoke("plot", str(run), str(runs[1]), "--out", str(tmp_path / "cmp"))
    assert code == 0 and list((tmp_path / "cmp").glob("compare_*.png")), text


def test_determinism_same_spec_same_states(tmp_path: Path) -> None:
    """Two runs of the same spec and seed log identical /sim/state streams."""
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.runs.runner import run as simulate
    from walkrepro.specs.files import load_spec

    path = tmp_path / "ok.yaml"
    path.write_text(
        SPEC.replace("{key: walkrepro}", "{key: walkrepro}\nsensors: {joint_position_noise: 0.001}")
    )
    spec = resolve_spec(load_spec(str(path))).spec
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    simulate(spec, a)
    simulate(spec, b)
    sa = record.read_log(a).messages(record.TOPIC_STATE)
    sb = record.read_log(b).messages(record.TOPIC_STATE)
    assert len(sa) > 100 and sa == sb


@pytest.mark.slow
def test_sigint_leaves_readable_interrupted_log(tmp_path: Path) -> None:
    """Ctrl-C during a run leaves a readable log marked 'interrupted' in a finished run directory."""
    path = tmp_path / "long.yaml"
    path.write_text(SPEC.replace("duration: 0.3", "duration: 60"))
    out = tmp_path / "runs"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "walkrepro", "run", str(path), "--out", str(out), "--no-figures"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
    )
    # Wait until the log exists and has grown, i.e. the loop is running.
    deadline = time.monotonic() + 120
    logs: list[Path] = []
    while time.monotonic() < deadline:
        logs = list(out.glob("tiny_stand/*/log.mcap"))
        if logs and logs[0].stat().st_size > 0:
            break
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    output, _ = proc.communicate(timeout=120)
    text = output.decode()
    assert proc.returncode == 130, text
    assert "Traceback" not in text
    runs = [r for r in (out / "tiny_stand").iterdir() if not r.name.startswith(".")]
    assert len(runs) == 1
    log = record.read_log(runs[0] / "log.mcap")
    assert log.metadata["outcome"] == "interrupted"
    assert len(log.messages(record.TOPIC_STATE)) > 10
    assert json.loads((runs[0] / "run.json").read_text())["outcome"] == "interrupted"


def test_save_reference_copies_metrics_and_figures(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run's metrics, verdict and PNGs become the experiment's committed reference, replacing old PNGs."""
    from walkrepro.runs import results

    run = tmp_path / "runs" / "tiny_stand" / "20260101T000000Z-abcdef"
    (run / "figures").mkdir(parents=True)
    for name in ("metrics.json", "check.json", "run.json"):
        (run / name).write_text("{}")
    (run / "figures" / "overview.png").write_bytes(b"png")
    (run / "figures" / "overview.svg").write_text("<svg/>")
    monkeypatch.setattr(results, "RESULTS_DIR", tmp_path / "results")
    stale = tmp_path / "results" / "tiny_stand" / "figures" / "old.png"
    stale.parent.mkdir(parents=True)
    stale.write_bytes(b"old")
    target = results.save_reference(run)
    assert target == tmp_path / "results" / "tiny_stand"
    assert sorted(p.name for p in target.iterdir()) == [
        "check.json",
        "figures",
        "metrics.json",
        "run.json",
    ]
    assert [p.name for p in (target / "figures").iterdir()] == ["overview.png"]


def test_check_prints_one_line_per_experiment_and_failing_rows_in_full(tmp_path: Path) -> None:
    """`check` prints one line per experiment and the summary; a failing row is printed in full, --details prints all rows."""
    path = tmp_path / "fails.yaml"
    long_source = "a source long enough to wrap " * 8
    path.write_text(
        SPEC.replace(
            "source: test}",
            f"source: test}}\n  - {{metric: fell, op: '==', value: 1, "
            f"source: '{long_source.strip()}'}}",
        )
    )
    code, text = invoke("run", str(path), "--out", str(tmp_path / "runs"))
    assert code == 0 or code == 1, text
    (run,) = (tmp_path / "runs" / "tiny_stand").iterdir()
    code, text = invoke("check", "--run", str(run))
    assert code == 1, text
    lines = text.splitlines()
    assert sum(line.startswith("FAIL  tiny_stand") for line in lines) == 1, text
    # The failing row, whole (its long source on one line, never cut); the passing row not.
    assert "  failed  tiny_stand · fell == 1: measured 0" in lines, text
    assert f"          source: {long_source.strip()}" in lines, text
    assert "== 0" not in text, text
    assert lines[-1] == "all rows: 1 reproduced, 0 calibrated, 0 known deviations, 1 failed", text
    code, details = invoke("check", "--run", str(run), "--details")
    assert code == 1 and "paper expectations" in details and "reproduced" in details, details
    assert details.splitlines()[-1] == lines[-1]


def test_passing_check_is_two_lines(tmp_path: Path) -> None:
    """A passing experiment takes one line, the count line another; nothing else (no table)."""
    path = tmp_path / "ok.yaml"
    path.write_text(SPEC)
    code, text = invoke("run", str(path), "--out", str(tmp_path / "runs"))
    assert code == 0, text
    (run,) = (tmp_path / "runs" / "tiny_stand").iterdir()
    code, text = invoke("check", "--run", str(run))
    assert code == 0, text
    assert text.splitlines() == [
        "ok    tiny_stand  complete    1 reproduced, 0 calibrated, 0 known deviations, 0 failed",
        "all rows: 1 reproduced, 0 calibrated, 0 known deviations, 0 failed",
    ]


@pytest.mark.parametrize("shell", ["bash", "zsh", "fish"])
def test_show_completion_prints_a_script(shell: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """`--show-completion SHELL` prints a completion script for walkrepro (what --install-completion installs)."""
    # Typer reads this when it builds the command: the shell is then an argument, not detected.
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    result = CliRunner().invoke(app, ["--show-completion", shell], prog_name="walkrepro")
    assert result.exit_code == 0, result.output
    assert f"complete_{shell}" in result.output and "_WALKREPRO_COMPLETE" in result.output


def test_unknown_completion_shell_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A shell Typer cannot complete for is an error, not an empty script."""
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    result = CliRunner().invoke(app, ["--show-completion", "cmd.exe"], prog_name="walkrepro")
    assert result.exit_code != 0
    assert "_WALKREPRO_COMPLETE" not in result.output


#: The walkrepro command as the shell's completion calls it (the console script's name).
COMPLETE = [sys.executable, "-c", "from walkrepro.cli import app; app(prog_name='walkrepro')"]


def test_completion_offers_commands_and_experiment_names() -> None:
    """Tab completion (the script --install-completion installs) completes command names and `check`'s experiments."""
    env = {**os.environ, "_WALKREPRO_COMPLETE": "complete_bash", "COMP_CWORD": "2"}
    done = subprocess.run(
        COMPLETE,
        env={**env, "COMP_WORDS": "walkrepro check stand_"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.stdout.split() == [
        "stand_coman",
        "stand_coman_lab",
        "stand_dyros_red",
        "stand_kist_humanoid",
    ], done
    done = subprocess.run(
        COMPLETE,
        env={**env, "COMP_WORDS": "walkrepro ch", "COMP_CWORD": "1"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.stdout.split() == ["check"], done


TWO_CLAIMS = SPEC + (
    '  - {metric: pelvis_drift, op: "<", value: 0.0, source: "test: an impossible claim"}\n'
)


def test_run_prints_one_line_per_claim_and_failing_rows_in_full(tmp_path: Path) -> None:
    """`walkrepro run` prints a line per claim (status, claim, paper value, measured), the
    failing row again in full with its source, the count line and the run directory;
    --details prints the full table instead."""
    path = tmp_path / "claims.yaml"
    path.write_text(TWO_CLAIMS)
    out = tmp_path / "runs"
    code, text = invoke("run", str(path), "--out", str(out), "--no-figures")
    assert code == 1, text  # a failing claim fails the command, as `check` does
    lines = text.strip().splitlines()
    claims = [line for line in lines if " paper " in line and " measured " in line]
    assert len(claims) == 2
    assert claims[0].split()[:5] == ["reproduced", "fell", "paper", "==", "0"]
    assert claims[1].split()[:5] == ["failed", "pelvis_drift", "paper", "<", "0"]
    assert "source: test: an impossible claim" in text  # the failing row in full
    assert "test: an impossible claim" not in "\n".join(claims)
    assert "1 reproduced, 0 calibrated, 0 known deviations, 1 failed" in text
    assert lines[-1].startswith("run directory: ")
    assert len(lines) == 2 + 3 + 1 + 1  # claims, the failing row's 3 lines, count, directory
    code, details = invoke("run", str(path), "--out", str(out), "--no-figures", "--details")
    assert code == 1 and "source / note" in details and "paper expectations" in details


def test_forward_walks_verdict_fits_in_thirty_lines(capsys: pytest.CaptureFixture) -> None:
    """The verdict `walkrepro run forward_walk` prints for its committed reference, with the
    run directory, figures, video and progress lines around it, stays within 30 lines."""
    import math

    from walkrepro import REFERENCES_DIR
    from walkrepro.cli.verdicts import print_verdicts
    from walkrepro.evaluation.checks import CheckRow, Verdict

    saved = json.loads((REFERENCES_DIR / "forward_walk" / "check.json").read_text())

    def row(r: dict) -> CheckRow:
        observed = r["observed"]
        return CheckRow(
            metric=r["metric"],
            op=r["op"],
            paper=tuple(r["paper"]) if isinstance(r["paper"], list) else r["paper"],
            measured=math.nan if r["measured"] is None else r["measured"],
            status=r["status"],
            source=r["source"],
            note=r["note"],
            observed=tuple(observed) if isinstance(observed, list) else observed,
            claim=r.get("claim"),
            own=r.get("own"),
        )

    verdict = Verdict("forward_walk", saved["outcome"], tuple(row(r) for r in saved["rows"]))
    print_verdicts([verdict], details=False, per_claim=True)
    printed = capsys.readouterr().out.strip().splitlines()
    # one line per row, the paper's claims line, the all-rows line, and the failures' details
    assert len(printed) == len(verdict.rows) + 2 + sum(
        3 if r.note else 2 for r in verdict.rows if r.status == "fail"
    )
    assert len(printed) + 4 <= 30  # + run directory, figures, video, the progress bar


def test_check_with_jobs_runs_on_the_sweep_pool_and_reports_each_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`check --jobs 2` runs its experiments on the sweep's process pool: each run is
    reported as it finishes and checked, as with one job."""
    specs = tmp_path / "specs"
    specs.mkdir()
    for name in ("tiny_a", "tiny_b"):
        (specs / f"{name}.yaml").write_text(SPEC.replace("tiny_stand", name))
    out = tmp_path / "runs"
    monkeypatch.setenv("WALKREPRO_EXPERIMENTS", str(specs))  # what --experiments sets
    code, text = invoke("check", "--jobs", "2", "--out", str(out))
    assert code == 0, text
    assert "with 2 process(es)" in text and "[1/2]" in text and "[2/2]" in text
    for name in ("tiny_a", "tiny_b"):
        assert any(line.split()[:3] == ["ok", name, "complete"] for line in text.splitlines()), text
        assert len(list((out / name).iterdir())) == 1


def test_check_on_local_ray_reports_each_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`check --engine ray` runs the experiments as Ray tasks, with the same verdicts."""
    pytest.importorskip("ray")
    specs = tmp_path / "specs"
    specs.mkdir()
    for name in ("tiny_a", "tiny_b"):
        (specs / f"{name}.yaml").write_text(SPEC.replace("tiny_stand", name))
    monkeypatch.setenv("WALKREPRO_EXPERIMENTS", str(specs))
    out = tmp_path / "runs"
    code, text = invoke("check", "--jobs", "2", "--engine", "ray", "--out", str(out))
    assert code == 0, text
    assert "with Ray (2 CPUs)" in text and "[2/2]" in text
    assert "2 reproduced, 0 calibrated, 0 known deviations, 0 failed" in text


def test_check_engine_options_are_checked() -> None:
    """An unknown engine, or --address without Ray, is a one-paragraph error."""
    assert_friendly(*invoke("check", "stand_coman", "--engine", "dask"), "Valid engines")
    assert_friendly(*invoke("check", "stand_coman", "--address", "auto"), "--engine ray only")


def test_every_commands_help_is_a_first_line_and_paragraphs_that_rich_wraps() -> None:
    """Each command's help is one first line, then paragraphs without hard line breaks
    (rich keeps them, so a docstring's breaks would cut sentences on any other width)."""
    from walkrepro.cli import reflow

    for info in app.registered_commands:
        assert info.help, info.callback
        first, *rest = info.help.split("\n\n")
        assert "\n" not in first and len(first) <= 100, first
        for paragraph in rest:
            assert all(line.startswith("- ") for line in paragraph.splitlines()[1:]), paragraph
    assert reflow("A.\n\nB b\nc.\n- one\n- two") == "A.\n\nB b c.\n- one\n- two"
    code, out = invoke("-h")
    assert code == 0 and "List every number an experiment's run uses" in out


def test_the_app_module_stays_thin_and_the_command_modules_short() -> None:
    """The command's app module (``walkrepro/cli/__init__.py``: the typer app, the process
    set-up and the registration of the commands) is under 300 lines, no function of the
    command's modules is over 80, and every command is defined in a group module of its own."""
    import ast
    import inspect

    import walkrepro.cli

    package = Path(walkrepro.cli.__file__).parent
    assert len((package / "__init__.py").read_text().splitlines()) < 300
    for module in sorted(package.glob("*.py")):
        for node in ast.walk(ast.parse(module.read_text(), str(module))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                assert node.end_lineno - first + 1 <= 80, f"{module.name}: {node.name}"
    for info in app.registered_commands:
        where = inspect.unwrap(info.callback).__module__
        assert where.startswith("walkrepro.cli.") and where != "walkrepro.cli.common", where
