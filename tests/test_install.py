"""walkrepro as a library: a user's own folder of specs (``--experiments DIR``), and an
installed wheel that runs the shipped experiments from any directory (locations.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
from test_cli import SPEC
from typer.testing import CliRunner

from walkrepro import locations
from walkrepro.cli import app

ROOT = Path(__file__).resolve().parents[1]
#: What a wheel is not built from: git, build products, runs and their logs.
NOT_SOURCES = (".git", "build", "dist", "*.egg-info", "__pycache__", ".*_cache")
#: The folders runs and reports are written to, by path: the package's own ``runs/`` (the
#: loop) and ``publish/report/`` are sources.
NOT_SOURCE_DIRS = (ROOT / "results" / "runs", ROOT / "runs", ROOT / "report")


def _not_sources(folder: str, names: list[str]) -> set[str]:
    """``shutil.copytree``'s ``ignore``: the patterns above, and the run and report folders."""
    ignored = set(shutil.ignore_patterns(*NOT_SOURCES)(folder, names))
    return ignored | {name for name in names if Path(folder) / name in NOT_SOURCE_DIRS}


#: A user's own spec: the CLI tests' short standing run under another name.
USER_SPEC = SPEC.replace("name: tiny_stand", "name: my_stand")


@pytest.fixture
def user_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder with one spec; the environment variable --experiments sets is restored."""
    monkeypatch.setenv(locations.USER_EXPERIMENTS_ENV, "")  # undone after the test
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "my_stand.yaml").write_text(USER_SPEC)
    return folder


def test_the_checkout_is_found_in_place() -> None:
    assert locations.IS_CHECKOUT
    assert locations.EXPERIMENTS_DIR == ROOT / "experiments"
    assert locations.REFERENCES_DIR == locations.RESULTS_DIR == ROOT / "results"


def test_user_folder_is_listed_beside_the_shipped_experiments(user_folder: Path) -> None:
    result = CliRunner().invoke(app, ["--experiments", str(user_folder), "list"])
    assert result.exit_code == 0, result.output
    assert "my_stand" in result.output and "forward_walk" in result.output


def test_check_without_names_runs_the_user_folder_only(user_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "runs"
    result = CliRunner().invoke(
        app, ["--experiments", str(user_folder), "check", "--out", str(out), "--jobs", "1"]
    )
    assert result.exit_code == 0, result.output
    assert [p.name for p in out.iterdir() if p.name != ".walkrepro-output"] == ["my_stand"]
    assert "1 reproduced, 0 calibrated, 0 known deviations, 0 failed" in result.output


def test_a_shipped_name_is_found_with_a_user_folder(user_folder: Path) -> None:
    from walkrepro.specs.files import find_spec_file

    os.environ[locations.USER_EXPERIMENTS_ENV] = str(user_folder)
    assert find_spec_file("my_stand") == user_folder / "my_stand.yaml"
    assert find_spec_file("stand_coman") == locations.EXPERIMENTS_DIR / "stand_coman.yaml"


def test_an_unknown_name_lists_both_folders(user_folder: Path) -> None:
    result = CliRunner().invoke(app, ["--experiments", str(user_folder), "run", "my_stnad"])
    assert result.exit_code == 2, result.output
    assert "my_stand" in result.output and "Traceback" not in result.output


def test_a_missing_user_folder_is_a_clear_error() -> None:
    result = CliRunner().invoke(app, ["--experiments", "/no/such/folder", "list"])
    assert result.exit_code == 2
    assert "does not exist" in result.output and "Traceback" not in result.output


def _venv_with_this_environment(venv: Path) -> Path:
    """A fresh venv that borrows this environment's installed dependencies (mujoco, pin, ...)
    through a .pth file, so no download is needed. The venv's own site-packages comes first
    on sys.path, so the walkrepro installed there wins over this environment's (the test
    checks where it was imported from)."""
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    python = venv / "bin" / "python"
    site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    borrowed = dict.fromkeys([sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]])
    lines = [f"import site; site.addsitedir({d!r})" for d in borrowed]
    (Path(site) / "_walkrepro_test_deps.pth").write_text("\n".join(lines) + "\n")
    return python


@pytest.mark.slow
def test_an_installed_wheel_runs_a_shipped_experiment_from_any_directory(tmp_path: Path) -> None:
    """``pip install`` of the built wheel (not editable), then from an empty directory:
    ``walkrepro check stand_coman`` passes on the shipped spec, robot and references, the
    run lands in ./results, and writing the repository's files is refused."""
    # Built from a copy: an in-tree build leaves build/lib behind, whose stale files a later
    # wheel would carry.
    source = tmp_path / "source"
    shutil.copytree(ROOT, source, ignore=_not_sources)
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(source)],
        check=True,
    )
    (wheel,) = dist.glob("walkrepro-*.whl")
    python = _venv_with_this_environment(tmp_path / "venv")
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", str(wheel)], check=True)
    empty = tmp_path / "empty"
    empty.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY", "PYTHONPATH")}
    env.pop(locations.USER_EXPERIMENTS_ENV, None)

    def walkrepro(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [str(tmp_path / "venv" / "bin" / "walkrepro"), *args],
            cwd=empty,
            env=env,
            capture_output=True,
            text=True,
            timeout=600,
        )

    where = subprocess.run(
        [str(python), "-c", "import walkrepro; print(walkrepro.__file__, walkrepro.IS_CHECKOUT)"],
        cwd=empty,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert where.startswith(str(tmp_path / "venv")) and where.split()[-1] == "False", where

    checked = walkrepro("check", "stand_coman")
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert "2 reproduced, 0 calibrated, 0 known deviations, 0 failed" in checked.stdout
    assert (empty / "results" / "runs" / "stand_coman").is_dir()

    listed = walkrepro("list")
    assert listed.returncode == 0 and "forward_walk" in listed.stdout

    refused = walkrepro("docs")
    assert refused.returncode == 2 and "installed copy" in refused.stderr
    assert "Traceback" not in refused.stderr
