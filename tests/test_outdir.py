"""Output directories are walkrepro's or empty: every writing command refuses a user's folder
(unless --force), replaces its own output atomically, and says so in one paragraph (exit 2)
when the place is a file or read-only."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.errors import WalkreproError
from walkrepro.runtime import gl, outdir

runner = CliRunner()
STAND = ["stand_coman", "--set", "sim.duration=0.1"]


@pytest.fixture
def locked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A read-only directory (mode 555). Root may write into one anyway, so for root the
    operating system's refusal is simulated: access() says no, and creating anything under
    it raises PermissionError, as it would for any other user."""
    path = tmp_path / "locked"
    path.mkdir()
    path.chmod(0o555)
    if os.geteuid() == 0:
        real_access, real_mkdir, real_open = os.access, os.mkdir, os.open

        def inside(p: object) -> bool:
            return Path(os.fsdecode(p)).resolve().is_relative_to(path.resolve())  # type: ignore[arg-type]

        def access(p: object, mode: int, *a: object, **k: object) -> bool:
            return False if inside(p) and mode & os.W_OK else real_access(p, mode, *a, **k)

        def mkdir(p: object, *a: object, **k: object) -> None:
            if inside(p) and Path(os.fsdecode(p)) != path:  # type: ignore[arg-type]
                raise PermissionError(13, "Permission denied", os.fsdecode(p))  # type: ignore[arg-type]
            real_mkdir(p, *a, **k)

        def open_(p: object, flags: int, *a: object, **k: object) -> int:
            if inside(p) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
                raise PermissionError(13, "Permission denied", os.fsdecode(p))  # type: ignore[arg-type]
            return real_open(p, flags, *a, **k)

        monkeypatch.setattr(os, "access", access)
        monkeypatch.setattr(os, "mkdir", mkdir)
        monkeypatch.setattr(os, "open", open_)
    yield path
    path.chmod(0o755)


def _user_dir(path: Path) -> Path:
    """A user's folder: a notes file and a subfolder with data."""
    path.mkdir(parents=True)
    (path / "notes.txt").write_text("my notes")
    (path / "data").mkdir()
    (path / "data" / "thesis.tex").write_text("my thesis")
    return path


def _intact(path: Path) -> bool:
    return (path / "notes.txt").read_text() == "my notes" and (
        path / "data" / "thesis.tex"
    ).read_text() == "my thesis"


def _invoke(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, list(args))
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short stand_coman run (log, check.json)."""
    root = tmp_path_factory.mktemp("outdir") / "runs"
    code, text = _invoke("run", *STAND, "--out", str(root), "--no-figures")
    assert code == 0, text
    (directory,) = (root / "stand_coman").iterdir()
    return directory


# ---- the helper ----------------------------------------------------------------------


def test_a_new_root_is_created_with_the_marker_and_a_users_folder_is_refused(
    tmp_path: Path,
) -> None:
    """A missing root is created and marked; an empty one is taken; a user's folder is
    refused unless forced, and nothing in it is touched."""
    root = outdir.claim_root(tmp_path / "new")
    assert outdir.marker_kind(root) == outdir.RUNS
    (tmp_path / "empty").mkdir()
    assert outdir.marker_kind(outdir.claim_root(tmp_path / "empty")) == outdir.RUNS
    user = _user_dir(tmp_path / "mine")
    with pytest.raises(WalkreproError, match="did not write .*notes.txt.*--force"):
        outdir.claim_root(user)
    assert _intact(user) and not (user / outdir.MARKER).exists()
    outdir.claim_root(user, force=True)
    assert _intact(user) and outdir.marker_kind(user) == outdir.RUNS


def test_a_runs_root_written_before_the_marker_is_recognised(tmp_path: Path) -> None:
    """Run and sweep directories (<experiment>/<stamp>-<id>) are walkrepro's layout."""
    (tmp_path / "old" / "forward_walk" / "20260101T000000Z-abcdef").mkdir(parents=True)
    (tmp_path / "old" / "sweeps" / "in_place" / "20260101T000000Z-123456").mkdir(parents=True)
    outdir.claim_root(tmp_path / "old")
    (tmp_path / "old" / "forward_walk" / "essay.md").write_text("mine")
    (tmp_path / "old" / outdir.MARKER).unlink()
    with pytest.raises(WalkreproError, match="did not write"):
        outdir.claim_root(tmp_path / "old")


def test_a_file_and_a_read_only_directory_are_clean_errors(tmp_path: Path, locked: Path) -> None:
    """--out on a file, or in a read-only directory: WalkreproError, nothing created."""
    (tmp_path / "a_file").write_text("x")
    with pytest.raises(WalkreproError, match="that is a file"):
        outdir.claim_root(tmp_path / "a_file")
    with pytest.raises(WalkreproError, match="that is a file"):
        with outdir.replacing(tmp_path / "a_file"):
            pass
    with pytest.raises(WalkreproError, match="cannot write here"):
        outdir.claim_root(locked)
    with pytest.raises(WalkreproError, match="cannot write here"):
        outdir.claim_root(locked / "runs")
    with pytest.raises(WalkreproError, match="cannot write here"):
        with outdir.replacing(locked / "site"):
            pass
    with pytest.raises(WalkreproError, match="cannot write here"):
        outdir.check_file(locked / "x.rrd")
    assert list(locked.iterdir()) == []


def test_replacing_swaps_walkreproa_output_and_a_failure_keeps_the_old(tmp_path: Path) -> None:
    """An earlier output is replaced whole; an exception (Ctrl-C too) inside the block leaves
    it as it was and no temporary directory beside it."""
    out = tmp_path / "site"
    with outdir.replacing(out) as work:
        (work / "index.html").write_text("first")
    assert (out / "index.html").read_text() == "first"
    with pytest.raises(KeyboardInterrupt):
        with outdir.replacing(out) as work:
            (work / "index.html").write_text("half")
            raise KeyboardInterrupt
    assert (out / "index.html").read_text() == "first"
    with outdir.replacing(out) as work:
        (work / "index.html").write_text("second")
    assert (out / "index.html").read_text() == "second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]


# ---- each writing command ------------------------------------------------------------


def _fake_results(root: Path) -> Path:
    """A results tree of one experiment (forward_walk), enough for a report."""
    from walkrepro.specs.files import load_spec

    directory = root / "forward_walk"
    directory.mkdir(parents=True)
    row = {
        "metric": "walk_speed",
        "op": "between",
        "paper": [0.088, 0.132],
        "measured": 0.11,
        "status": "pass",
        "source": "s",
        "note": "",
        "observed": None,
    }
    (directory / "check.json").write_text(json.dumps({"outcome": "complete", "rows": [row]}))
    spec = load_spec("forward_walk").spec
    (directory / "spec.yaml").write_text(spec.model_copy(update={"sweeps": []}).to_yaml())
    return root


def test_report_keeps_a_users_folder_and_replaces_its_own(tmp_path: Path) -> None:
    """`report --out mydir` refuses a folder with the user's files (exit 2, all kept);
    `--out .` in a project likewise; its own earlier report is replaced; a failure while
    building leaves the old report and no .partial."""
    source = _fake_results(tmp_path / "results")
    user = _user_dir(tmp_path / "mydir")
    code, text = _invoke("report", "--from", str(source), "--out", str(user))
    assert code == 2 and "did not write" in text and "--force" in text
    assert _intact(user)
    here = Path.cwd()
    os.chdir(user)
    try:
        code, text = _invoke("report", "--from", str(source), "--out", ".")
    finally:
        os.chdir(here)
    assert code == 2 and _intact(user)
    site = tmp_path / "site"
    code, text = _invoke("report", "--from", str(source), "--out", str(site))
    assert code == 0, text
    first = (site / "index.html").read_text()
    code, text = _invoke("report", "--from", str(source), "--out", str(site))
    assert code == 0, text
    assert outdir.marker_kind(site) == outdir.REPORT

    import walkrepro.publish.report.site as report_site

    def broken(*args: object) -> str:
        raise RuntimeError("disk full")

    original = report_site._index
    report_site._index = broken  # type: ignore[assignment]
    try:
        with pytest.raises(RuntimeError):
            report_site.build_report(source, site)
    finally:
        report_site._index = original  # type: ignore[assignment]
    assert (site / "index.html").read_text() == first
    assert not [p for p in tmp_path.iterdir() if "partial" in p.name or ".old" in p.name]


def test_report_on_a_file_or_read_only_place_is_one_paragraph(tmp_path: Path, locked: Path) -> None:
    """--out naming a file, or inside a read-only directory: exit 2, no traceback, no
    .partial left."""
    source = _fake_results(tmp_path / "results")
    (tmp_path / "a_file").write_text("x")
    code, text = _invoke("report", "--from", str(source), "--out", str(tmp_path / "a_file"))
    assert code == 2 and "that is a file" in text
    code, text = _invoke("report", "--from", str(source), "--out", str(locked / "s"))
    assert code == 2 and "cannot write here" in text
    assert list(locked.iterdir()) == []
    assert not [p for p in tmp_path.iterdir() if "partial" in p.name]


def test_run_and_check_refuse_a_users_folder_as_out(tmp_path: Path) -> None:
    """`run --out` and `check --out` on a folder with the user's files: exit 2 before any
    run, everything kept; a file as --out is a clean error too."""
    user = _user_dir(tmp_path / "project")
    code, text = _invoke("run", *STAND, "--out", str(user), "--no-figures")
    assert code == 2 and "did not write" in text and _intact(user)
    assert sorted(p.name for p in user.iterdir()) == ["data", "notes.txt"]
    code, text = _invoke("check", *STAND, "--out", str(user), "--jobs", "1")
    assert code == 2 and "did not write" in text and _intact(user)
    (tmp_path / "a_file").write_text("x")
    code, text = _invoke("run", *STAND, "--out", str(tmp_path / "a_file"))
    assert code == 2 and "that is a file" in text


def test_run_into_an_earlier_runs_root_and_with_force(tmp_path: Path, run_dir: Path) -> None:
    """A runs root walkrepro wrote takes more runs; --force writes beside the user's files
    (which stay)."""
    root = run_dir.parent.parent
    assert outdir.marker_kind(root) == outdir.RUNS
    user = _user_dir(tmp_path / "project")
    code, text = _invoke("run", *STAND, "--out", str(user), "--no-figures", "--force")
    assert code == 0, text
    assert _intact(user) and len(list((user / "stand_coman").iterdir())) == 1


def test_sweep_refuses_a_users_folder_and_a_bad_engine_leaves_nothing(tmp_path: Path) -> None:
    """`sweep --out mydir` refuses the user's folder; --jobs 0 and --engine dask are refused
    before a sweep directory is made."""
    user = _user_dir(tmp_path / "mine")
    grid = ["sweep", "stand_coman", "--grid", "sim.duration=0.05,0.1"]
    code, text = _invoke(*grid, "--out", str(user), "--jobs", "1")
    assert code == 2 and "did not write" in text and _intact(user)
    assert not (user / "sweeps").exists()
    for bad in (["--jobs", "0"], ["--engine", "dask"]):
        code, text = _invoke(*grid, "--out", str(tmp_path / "sw"), *bad)
        assert code == 2, text
        assert not (tmp_path / "sw").exists(), bad


def test_plot_out_refuses_a_users_folder(tmp_path: Path, run_dir: Path) -> None:
    """`plot RUN --out mydir` would write figures among the user's files: refused."""
    user = _user_dir(tmp_path / "mine")
    code, text = _invoke("plot", str(run_dir), "--out", str(user))
    assert code == 2 and "did not write" in text and _intact(user)


def test_export_out_refuses_a_directory_a_users_file_and_a_read_only_place(
    tmp_path: Path, run_dir: Path, locked: Path
) -> None:
    """`export --out` on a directory, an existing file (without --force) or a read-only
    directory: exit 2, one paragraph, the file kept, nothing partial left."""
    pytest.importorskip("rerun")
    user = _user_dir(tmp_path / "mine")
    code, text = _invoke("export", str(run_dir), "--rerun", "--out", str(user))
    assert code == 2 and "that is a directory" in text
    code, text = _invoke("export", str(run_dir), "--rerun", "--out", str(user / "notes.txt"))
    assert code == 2 and "exists" in text and _intact(user)
    code, text = _invoke("export", str(run_dir), "--rerun", "--out", str(locked / "x.rrd"))
    assert code == 2 and "cannot write here" in text
    assert list(locked.iterdir()) == []


@pytest.mark.skipif(not gl.available(), reason="no OpenGL backend")
def test_render_out_keeps_a_users_file_and_says_a_read_only_place(
    tmp_path: Path, run_dir: Path, locked: Path
) -> None:
    """`render --out` an existing file is refused without --force (and replaced with it);
    a directory, a read-only place and an empty --at are clean errors."""
    user = _user_dir(tmp_path / "mine")
    picture = user / "photo.png"
    picture.write_bytes(b"my photo")
    code, text = _invoke("render", str(run_dir), "--at", "0", "--out", str(picture))
    assert code == 2 and "exists" in text
    assert picture.read_bytes() == b"my photo"
    code, text = _invoke("render", str(run_dir), "--at", "0", "--out", str(user))
    assert code == 2 and "that is a directory" in text
    code, text = _invoke("render", str(run_dir), "--at", "", "--out", str(tmp_path / "s.png"))
    assert code == 2 and "at least one time" in text
    code, text = _invoke("render", str(run_dir), "--width", "-5", "--out", str(tmp_path / "s.png"))
    assert code == 2 and "--width" in text
    code, text = _invoke("render", str(run_dir), "--at", "0", "--out", str(picture), "--force")
    assert code == 0, text
    assert picture.read_bytes()[:4] == b"\x89PNG"
    assert [p.name for p in user.iterdir() if "partial" in p.name] == []
    code, text = _invoke("render", str(run_dir), "--at", "0", "--out", str(locked / "a.png"))
    assert code == 2 and "cannot write here" in text


def test_a_failed_export_leaves_no_partial_file(tmp_path: Path) -> None:
    """writing_file: a failure deletes the temporary file and keeps the old one."""
    out = tmp_path / "x.rrd"
    out.write_text("old")
    with pytest.raises(RuntimeError):
        with outdir.writing_file(out) as partial:
            partial.write_text("half")
            raise RuntimeError("boom")
    assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["x.rrd"]
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_run_given_a_run_directory_says_what_it_is(run_dir: Path, tmp_path: Path) -> None:
    """`walkrepro run DIR` on a run directory names it and the command to use (exit 2)."""
    code, text = _invoke("run", str(run_dir))
    assert code == 2 and "that is a run directory" in text and "check --run" in text
    code, text = _invoke("run", str(tmp_path))
    assert code == 2 and "that is a directory" in text


def test_python_overrides_are_not_called_set(tmp_path: Path) -> None:
    """Errors of walkrepro.load's overrides name them as overrides, not as --set; the CLI's
    still say --set."""
    import walkrepro

    with pytest.raises(WalkreproError) as raised:
        walkrepro.load("stand_coman", {"sim.duration": -1})
    assert "--set" not in str(raised.value) and "set by an override" in str(raised.value)
    with pytest.raises(WalkreproError) as raised:
        walkrepro.load("stand_coman", ["sim.duration"])
    assert "--set" not in str(raised.value) and "override 'sim.duration'" in str(raised.value)
    code, text = _invoke("run", "stand_coman", "--set", "sim.duration=-1")
    assert code == 2 and "(set with --set)" in text
