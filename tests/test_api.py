"""The library API (walkrepro.load, run, evaluate) and an import of walkrepro without side
effects."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

import walkrepro
from walkrepro.errors import SpecError, UnknownNameError

NO_SIDE_EFFECTS = (
    "import os, signal, sys\n"
    "e = dict(os.environ); h = signal.getsignal(signal.SIGINT)\n"
    "t = signal.getsignal(signal.SIGTERM)\n"
    "import walkrepro\n"
    "assert dict(os.environ) == e, set(os.environ.items()) ^ set(e.items())\n"
    "assert signal.getsignal(signal.SIGINT) is h and signal.getsignal(signal.SIGTERM) is t\n"
    "assert not {'numpy', 'mujoco', 'numba'} & set(sys.modules), 'a heavy import'\n"
)


@pytest.mark.parametrize("argv0", ["-c", "walkrepro"])
def test_importing_walkrepro_changes_no_environment_and_no_signal_handler(argv0: str) -> None:
    """Importing walkrepro leaves the environment, the SIGINT and SIGTERM handlers and the
    heavy libraries alone, also in a process named like the command."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env.pop("OPENBLAS_NUM_THREADS", None)
    code = f"import sys; sys.argv[0] = {argv0!r}\n" + NO_SIDE_EFFECTS
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_importing_the_api_and_the_papers_controllers_changes_nothing() -> None:
    """Importing walkrepro.api and each paper's controller module (which define their kernels
    and records) leaves the environment and the SIGINT and SIGTERM handlers alone."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env.pop("OPENBLAS_NUM_THREADS", None)
    code = (
        "import os, signal\n"
        "e = dict(os.environ); h = signal.getsignal(signal.SIGINT)\n"
        "t = signal.getsignal(signal.SIGTERM)\n"
        "import walkrepro, walkrepro.api\n"
        "import walkrepro.papers.lee2021.controller, walkrepro.papers.faraji.controller\n"
        "import walkrepro.papers.jo_oh.controller\n"
        "assert dict(os.environ) == e, set(os.environ.items()) ^ set(e.items())\n"
        "assert signal.getsignal(signal.SIGINT) is h and signal.getsignal(signal.SIGTERM) is t\n"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_using_the_library_leaves_the_environment_and_handlers_alone(tmp_path: Path) -> None:
    """load() and run() change no environment variable and leave the signal handlers as they
    found them; numba's cache is walkrepro's source-keyed directory, through numba.config."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env.pop("OPENBLAS_NUM_THREADS", None)
    code = (
        "import os, signal, sys\n"
        "e = dict(os.environ); h = signal.getsignal(signal.SIGINT)\n"
        "import walkrepro\n"
        "exp = walkrepro.load('stand_dyros_red', {'sim.duration': 0.05})\n"
        "done = walkrepro.run(exp, out=sys.argv[1])\n"
        "assert done.outcome == 'complete', done.result.message\n"
        "assert dict(os.environ) == e, set(os.environ.items()) ^ set(e.items())\n"
        "assert signal.getsignal(signal.SIGINT) is h\n"
        "from numba.core import config\n"
        "assert os.path.basename(config.CACHE_DIR).startswith('walkrepro-'), config.CACHE_DIR\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path)], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr


def test_the_command_does_its_own_set_up() -> None:
    """The command's set-up sets OPENBLAS_NUM_THREADS (unless the user did) and numba's cache
    directory, which child processes inherit."""
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",)}
    env.pop("OPENBLAS_NUM_THREADS", None)
    code = (
        "import os\nfrom walkrepro.cli import command_setup\ncommand_setup()\n"
        "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ['NUMBA_CACHE_DIR'])\n"
    )
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    threads, cache = done.stdout.split()
    assert threads == "1" and Path(cache).name.startswith("walkrepro-")


def test_load_resolves_the_experiment_once() -> None:
    """load() gives the validated spec with its overrides, the robot, the compiled scene and
    the controller's typed parameters; a mapping and --set strings are the same overrides."""
    exp = walkrepro.load("stand_dyros_red", {"sim.duration": 0.25, "sim.seed": 3})
    assert exp.name == "stand_dyros_red" and exp.spec.sim.duration == 0.25
    assert exp.overrides == ("sim.duration=0.25", "sim.seed=3")
    assert exp.robot.name == exp.spec.robot == "dyros_red"
    assert exp.scene.model.opt.timestep == exp.spec.sim.timestep
    assert exp.params.model_dump(mode="json") == exp.spec.controller.params
    same = walkrepro.load("stand_dyros_red", ["sim.duration=0.25", "sim.seed=3"])
    assert same.spec == exp.spec


def test_load_errors_name_the_field_or_the_valid_names() -> None:
    """A bad override is a spec error naming the field; an unknown name lists the valid ones."""
    with pytest.raises(SpecError, match="sim.duration"):
        walkrepro.load("stand_dyros_red", {"sim.duration": -1})
    with pytest.raises(UnknownNameError, match="stand_dyros_red"):
        walkrepro.load("stand_dyros_rde")


def test_run_and_evaluate_give_the_verdict_from_the_log(tmp_path: Path) -> None:
    """A short run writes a run directory with its log, metrics and verdict; evaluating the
    run, its directory or its log again gives the same rows."""
    exp = walkrepro.load("stand_dyros_red", {"sim.duration": 0.3})
    done = walkrepro.run(exp, out=tmp_path)
    assert isinstance(done, walkrepro.Run)
    assert done.outcome == "complete" and done.log_path.is_file()
    assert done.run_dir.parent == tmp_path / "stand_dyros_red"
    assert not math.isnan(done.metrics["pelvis_drift"])
    rows = [(r.metric, r.status, r.measured) for r in done.verdict.rows]
    assert rows and all(done.metrics[m] == measured for m, _, measured in rows)
    for again in (done, done.run_dir, done.log_path):
        verdict = walkrepro.evaluate(again)
        assert [(r.metric, r.status, r.measured) for r in verdict.rows] == rows


def test_run_takes_a_name_with_overrides(tmp_path: Path) -> None:
    """run(name, overrides) loads the experiment itself and records the overrides."""
    import json

    done = walkrepro.run("stand_dyros_red", {"sim.duration": 0.1}, out=tmp_path)
    record = json.loads((done.run_dir / "run.json").read_text())
    assert record["overrides"] == ["sim.duration=0.1"] and done.outcome == "complete"
    with pytest.raises(TypeError, match="load"):
        walkrepro.run(walkrepro.load("stand_dyros_red"), {"sim.duration": 0.1}, out=tmp_path)


def test_evaluate_of_a_missing_run_is_a_clear_error(tmp_path: Path) -> None:
    """evaluate() of a path that is no run is a walkrepro error, not a traceback's."""
    with pytest.raises(walkrepro.errors.WalkreproError):
        walkrepro.evaluate(tmp_path / "nothing")


def test_the_readmes_library_tour_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """The README's library tour runs as written (its runs go to a temporary root) and
    prints each claim of the run."""
    import re

    from walkrepro.locations import PROJECT_ROOT
    from walkrepro.runs import results

    readme = (PROJECT_ROOT / "README.md").read_text()
    tour = readme.split("## Library tour", 1)[1]
    (code,) = re.findall(r"```python\n(.*?)```", tour.split("\n## ", 1)[0], re.S)
    monkeypatch.setattr(results, "DEFAULT_ROOT", tmp_path)
    exec(compile(code, "README.md", "exec"), {})  # noqa: S102 - the README's own example
    printed = capsys.readouterr().out.splitlines()
    assert printed == ["fell == 0 0 pass", printed[1]] and printed[1].startswith("pelvis_drift <")
    assert list((tmp_path / "stand_dyros_red").iterdir())
