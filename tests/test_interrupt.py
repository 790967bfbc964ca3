"""Ctrl-C or SIGTERM at any moment, or a crash, leaves a useful run: run.json names the
outcome, metrics.json and check.json are written, and check --run re-checks it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from walkrepro.cli import app
from walkrepro.runtime.interrupt import InterruptFlag

SPEC = """\
name: tiny_walk_stand
description: a standing run long enough to interrupt
paper: {key: walkrepro}
robot: dyros_red
controller: {type: posture}
sim: {timestep: 0.0005, control_period: 0.001, duration: 60}
expect:
  - {metric: fell, op: "==", value: 0, source: test}
  - {metric: pelvis_drift, op: "<", value: 0.02, source: test}
"""


def interrupt_run(
    args: list[str],
    out: Path,
    after_loop_start: float | None,
    signum: int = signal.SIGINT,
) -> tuple[int, str]:
    """Start ``walkrepro run``, send ``signum`` ``after_loop_start`` seconds after its log
    appears (None: as soon as its run directory appears, before the simulation), and return
    (exit code, output)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "walkrepro", "run", *args, "--out", str(out), "--no-figures"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
    )
    if after_loop_start is None:
        # The run directory appears once the spec is valid, before the slow imports and the
        # set-up: a signal then comes before the simulation starts.
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not list(out.glob("*/.*.partial")):
            time.sleep(0.01)
    else:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not list(out.glob("*/.*.partial/log.mcap")):
            time.sleep(0.05)
        time.sleep(after_loop_start)
    proc.send_signal(signum)
    output, _ = proc.communicate(timeout=300)
    return proc.returncode, output.decode()


def only_run(out: Path) -> Path:
    runs = [r for r in out.glob("*/*") if r.is_dir() and not r.name.startswith(".")]
    assert len(runs) == 1, runs
    return runs[0]


def assert_useful(run: Path, code: int, text: str, exit_code: int = 130) -> dict:
    """Exit 130 (143 after SIGTERM), no traceback, run.json says interrupted, metrics.json
    with a reason for each null, check.json written."""
    assert code == exit_code, text
    assert json.loads((run / "run.json").read_text())["outcome"] == "interrupted"
    assert "Traceback" not in text, text
    saved = json.loads((run / "metrics.json").read_text())
    nulls = {k for k, v in saved["metrics"].items() if v is None}
    assert nulls and nulls == set(saved["not_measurable"]), saved
    assert all(saved["not_measurable"].values())
    check = json.loads((run / "check.json").read_text())
    assert check["outcome"] == "interrupted" and check["passed"] is False
    return saved


def recheck(run: Path) -> tuple[int, str]:
    from typer.testing import CliRunner

    result = CliRunner().invoke(app, ["check", "--run", str(run)])
    return result.exit_code, result.output


@pytest.mark.parametrize("moment", [None, 0.3, 2.0], ids=["set-up", "0.3 s", "2 s"])
def test_ctrl_c_at_any_moment_keeps_a_useful_run(tmp_path: Path, moment: float | None) -> None:
    """Ctrl-C in set-up or in the loop exits 130 with metrics.json (nulls with reasons) and check.json, and check --run re-checks it."""
    spec = tmp_path / "tiny_walk_stand.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "runs"
    code, text = interrupt_run([str(spec)], out, moment)
    run = only_run(out)
    saved = assert_useful(run, code, text)
    assert "fell" in saved["not_measurable"]  # unknown whether it would have fallen
    if moment is None:  # stopped before the simulation: not one step simulated
        assert json.loads((run / "run.json").read_text())["sim_time"] == 0.0
    code, text = recheck(run)
    assert code == 1 and "Traceback" not in text, text  # an interrupted run never passes
    assert "interrupted" in text


@pytest.mark.slow
@pytest.mark.parametrize("moment", [0.3, 4.0])
def test_ctrl_c_of_forward_walk(tmp_path: Path, moment: float) -> None:
    """The issue's case: Ctrl-C of forward_walk 0.3 s and 4 s after its loop starts leaves a re-checkable run.

    The walk is lengthened to 200 s simulated so that no machine finishes it before the
    Ctrl-C (at 4 s of wall time a fast one had already completed the 16.5 s walk)."""
    out = tmp_path / "runs"
    code, text = interrupt_run(["forward_walk", "--set", "sim.duration=200"], out, moment)
    run = only_run(out)
    assert_useful(run, code, text)
    code, text = recheck(run)
    assert code == 1 and "Traceback" not in text, text


def test_flag_takes_the_first_ctrl_c_and_the_second_raises() -> None:
    """Inside the flag the first SIGINT only sets it; the second raises KeyboardInterrupt; the old handler comes back."""
    before = signal.getsignal(signal.SIGINT)
    with InterruptFlag() as flag:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)
        assert flag.requested
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)
    assert signal.getsignal(signal.SIGINT) is before


@pytest.mark.parametrize(
    "moment", [None, 0.5, 3.0], ids=["before the loop", "0.5 s in the loop", "3 s in the loop"]
)
def test_sigterm_is_handled_like_ctrl_c(tmp_path: Path, moment: float | None) -> None:
    """SIGTERM (as schedulers and containers send) before or during the loop exits 143 with a finished, interrupted, re-checkable run directory."""
    spec = tmp_path / "tiny_walk_stand.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "runs"
    code, text = interrupt_run([str(spec)], out, moment, signal.SIGTERM)
    run = only_run(out)
    assert not list(out.glob("*/.*.partial"))
    assert_useful(run, code, text, exit_code=143)
    record = json.loads((run / "run.json").read_text())
    if moment is None:
        assert record["sim_time"] == 0.0
    else:
        assert record["sim_time"] > 0.0 and (run / "log.mcap").is_file()
    code, text = recheck(run)
    assert code == 1 and "Traceback" not in text, text
    assert "interrupted" in text


#: Runs ``walkrepro run`` in a child process with one library function replaced by one that
#: raises: a crash at a chosen stage, with no test hook in walkrepro itself.
CRASH = """
import sys
import {module} as target

def crash(*args, **kwargs):
    raise RuntimeError("forced crash for a test")

target.{name} = crash
from walkrepro.cli import app
app(sys.argv[1:])
"""


@pytest.mark.parametrize(
    "target",
    [
        "walkrepro.evaluation.metrics.evaluate",
        "walkrepro.present.figures.plot_run",
        "walkrepro.runs.runner._set_home",
    ],
    ids=["metrics", "figures", "set-up"],
)
def test_a_crash_leaves_an_error_run_directory(tmp_path: Path, target: str) -> None:
    """A crash in set-up, or after the loop (metrics, figures), leaves a finished run directory whose run.json says error with the message; check --run works on it."""
    module, name = target.rsplit(".", 1)
    out = tmp_path / "runs"
    args = ["run", "stand_coman", "--set", "sim.duration=0.05", "--out", str(out)]
    if name != "plot_run":
        args.append("--no-figures")
    proc = subprocess.run(
        [sys.executable, "-c", CRASH.format(module=module, name=name), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "forced crash for a test" in proc.stderr
    assert not list(out.glob("*/.*.partial"))
    run = only_run(out)
    assert f"run directory: {run}" in proc.stderr  # named under the traceback
    record = json.loads((run / "run.json").read_text())
    assert record["outcome"] == "error", record
    assert "RuntimeError: forced crash for a test" in record["message"]
    assert "Traceback" in record["traceback"]
    if name != "_set_home":
        assert record["run_outcome"] == "complete"  # the simulation itself had finished
    check = json.loads((run / "check.json").read_text())
    assert check["passed"] is False or name == "plot_run"  # figures crash after the verdict
    code, text = recheck(run)
    assert code in (0, 1) and "Traceback" not in text, text


def test_flag_takes_sigterm_like_ctrl_c_and_says_which() -> None:
    """The first SIGTERM only sets the flag (exit code 143); a following SIGINT raises; both old handlers come back."""
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with InterruptFlag() as flag:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.01)
        assert flag.requested and flag.signum == signal.SIGTERM and flag.exit_code == 143
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_a_run_without_log_is_rechecked_from_its_record(tmp_path: Path) -> None:
    """A run directory stopped before its log exists (run.json and spec.yaml only) re-checks as interrupted and verify says there is no log; one without spec.yaml is a one-paragraph error."""
    from walkrepro.runs import results
    from walkrepro.specs.files import load_spec

    spec = load_spec("stand_coman").spec
    run = results.abandon(
        results.new_run_dir(tmp_path, spec.name), spec.to_yaml(), spec.name, "interrupted", "x"
    )
    code, text = recheck(run)
    assert code == 1 and "interrupted" in text and "Traceback" not in text, text
    assert json.loads((run / "check.json").read_text())["outcome"] == "interrupted"
    from typer.testing import CliRunner

    verified = CliRunner().invoke(app, ["verify", str(run)])
    assert verified.exit_code == 2 and "nothing to verify" in verified.output, verified.output
    (run / "spec.yaml").unlink()
    code, text = recheck(run)
    assert code == 2 and "nothing to check" in text, text


# --- a stop signal during the imports, before any walkrepro handler ---------------------

HOLD = """
import os, signal, sys, time
sys.argv[0] = "walkrepro"  # as the console script
from walkrepro.runtime import interrupt
interrupt.hold_stop_signals_if_command()  # as the command's set-up does
interrupt.hold_stop_signals_if_command()  # a second call keeps the one hold
os.kill(os.getpid(), signal.{signal})  # while "importing"
time.sleep(0.05)
print("not stopped yet", flush=True)
{then}
"""


def _held(signum: str, then: str) -> subprocess.CompletedProcess:
    code = HOLD.format(signal=signum, then=then)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_a_signal_held_at_start_up_is_taken_over_by_the_run_flag() -> None:
    """A SIGTERM held since start-up is not lost: the first InterruptFlag starts requested, with the signal (exit code 143)."""
    then = "with interrupt.InterruptFlag() as flag:\n    print(flag.requested, flag.exit_code)"
    proc = _held("SIGTERM", then)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split("\n")[:2] == ["not stopped yet", "True 143"]


def test_a_signal_held_at_start_up_stops_a_sweep_block() -> None:
    """A SIGINT held since start-up raises KeyboardInterrupt as soon as a sweep's block starts, recording the signal."""
    then = (
        "received = interrupt.Received()\n"
        "try:\n"
        "    with interrupt.stop_signals_raise(received):\n"
        "        print('body ran')\n"
        "except KeyboardInterrupt:\n"
        "    print('stopped', received.exit_code)"
    )
    proc = _held("SIGINT", then)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split("\n")[:2] == ["not stopped yet", "stopped 130"]


def test_a_held_signal_nothing_takes_over_ends_the_process_at_exit() -> None:
    """A held SIGTERM that no flag takes over ends the process by SIGTERM when it exits: a stop is never lost."""
    proc = _held("SIGTERM", "print('command done', flush=True)")
    assert proc.returncode == -signal.SIGTERM, proc.stderr
    assert "command done" in proc.stdout


def test_only_the_command_holds_signals() -> None:
    """The console script and python -m walkrepro hold stop signals; a program importing walkrepro does not."""
    from walkrepro.runtime.interrupt import started_as_command

    assert started_as_command(["/usr/local/bin/walkrepro", "run"], [])
    assert started_as_command(["-m"], ["python", "-m", "walkrepro", "run"])
    assert not started_as_command(["-c"], ["python", "-c", "import walkrepro"])
    assert not started_as_command(["/usr/bin/pytest"], ["python", "/usr/bin/pytest"])


@pytest.mark.skipif(not Path("/proc/self/maps").is_file(), reason="needs Linux /proc")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_during_the_imports_leaves_an_interrupted_run(tmp_path: Path, signum: int) -> None:
    """SIGINT or SIGTERM while `walkrepro run` is still importing MuJoCo (no run directory yet) leaves a run directory with outcome interrupted and no step simulated."""
    out = tmp_path / "runs"
    proc = subprocess.Popen(
        ["walkrepro", "run", "stand_coman", "--out", str(out), "--no-figures"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    # The marker: MuJoCo's library is being loaded (after the hold, before any run).
    maps = Path(f"/proc/{proc.pid}/maps")
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and "mujoco" not in maps.read_text():
        time.sleep(0.002)
    assert not out.exists()  # no run directory yet: the signal comes during the imports
    proc.send_signal(signum)
    output = proc.communicate(timeout=300)[0].decode()
    assert proc.returncode == 128 + signum, output
    run = only_run(out)
    record = json.loads((run / "run.json").read_text())
    assert record["outcome"] == "interrupted" and record["sim_time"] == 0.0, record
    code, text = recheck(run)
    assert code == 1 and "interrupted" in text and "Traceback" not in text, text


def test_check_stopped_by_sigterm_exits_143(tmp_path: Path) -> None:
    """`walkrepro check` stopped by a scheduler's SIGTERM (to its process group, workers
    included) exits 143, as `run` does, not Ctrl-C's 130; nothing looks finished."""
    spec = tmp_path / "tiny_walk_stand.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "runs"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "walkrepro", "check", str(spec), "--jobs", "1", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        start_new_session=True,
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and not list(out.glob("*/.*.partial/log.mcap")):
        time.sleep(0.05)
    time.sleep(0.5)
    os.killpg(proc.pid, signal.SIGTERM)
    output, _ = proc.communicate(timeout=300)
    text = output.decode()
    assert proc.returncode == 143, text
    assert "Traceback" not in text
    record = json.loads((only_run(out) / "run.json").read_text())
    assert record["outcome"] == "interrupted"


def test_check_with_jobs_passes_a_stop_to_its_runs_and_reports_them(tmp_path: Path) -> None:
    """`walkrepro check --jobs 2` runs on the sweep's process pool, whose workers sit in their
    own process group: a Ctrl-C to the command alone reaches both runs under way, each keeps
    an interrupted run directory (stopped by SIGINT) and is reported; the command exits 130."""
    specs = tmp_path / "specs"
    specs.mkdir()
    for name in ("stand_one", "stand_two"):
        (specs / f"{name}.yaml").write_text(SPEC.replace("tiny_walk_stand", name))
    out = tmp_path / "runs"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "walkrepro", "--experiments", str(specs), "check"]
        + ["--jobs", "2", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        env=env,
        start_new_session=True,
    )
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and len(list(out.glob("*/.*.partial/log.mcap"))) < 2:
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)  # the command alone, not its workers' group
    text = proc.communicate(timeout=300)[0].decode()
    assert proc.returncode == 130, text  # the runs' own code: SIGINT reached them (143: SIGTERM)
    assert "Traceback" not in text
    for name in ("stand_one", "stand_two"):
        record = json.loads(only_run_of(out, name))
        assert record["outcome"] == "interrupted", record
        assert f"{name}: interrupted" in text, text


def only_run_of(out: Path, name: str) -> str:
    """The run.json text of the one run of ``name`` under ``out``."""
    (run,) = (out / name).iterdir()
    return (run / "run.json").read_text()
