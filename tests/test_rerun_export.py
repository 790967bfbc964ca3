"""``walkrepro export RUN --rerun``: the recording read back with Rerun's own reader, the
refusal to overwrite, and the one-line error without the Rerun SDK."""

from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from walkrepro import PROJECT_ROOT
from walkrepro.cli import app
from walkrepro.log.foxglove import body_names
from walkrepro.log.record import read_log
from walkrepro.present.rerun_export import INSTALL, body_entity, centre_of_pressure

runner = CliRunner()
#: stand_coman for 0.4 s, pushed at the torso from 0.1 s to 0.3 s.
PUSHED_STAND = (
    (PROJECT_ROOT / "experiments" / "stand_coman.yaml")
    .read_text()
    .replace("name: stand_coman", "name: pushed_stand")
    .replace("duration: 5.0", "duration: 0.4")
    + "disturbances:\n"
    + "  - {name: push, body: torso, frame: world, force: [40, 0, 0], start: 0.1, "
    + "duration: 0.2, profile: constant}\n"
)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run directory (log, check.json) of a short pushed stand."""
    root = tmp_path_factory.mktemp("rerun")
    spec = root / "pushed_stand.yaml"
    spec.write_text(PUSHED_STAND)
    result = runner.invoke(app, ["run", str(spec), "--out", str(root / "runs"), "--no-figures"])
    assert result.exit_code in (0, 1), result.output  # 1: a sanity row may fail; a log is made
    (directory,) = (root / "runs" / "pushed_stand").iterdir()
    return directory


@pytest.fixture(scope="module")
def recording(run_dir: Path) -> Path:
    """The run exported with the CLI's defaults (``RUN/log.rrd``)."""
    pytest.importorskip(
        "rerun", reason='the Rerun SDK is not installed: pip install "walkrepro[rerun]"'
    )
    result = runner.invoke(app, ["export", str(run_dir), "--rerun"])
    assert result.exit_code == 0, result.output
    return run_dir / "log.rrd"


def _columns(store: object) -> dict[str, dict[str, list]]:
    """Entity path -> column name -> every value (temporal and static rows) of a store."""
    out: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for chunk in store.stream():  # type: ignore[attr-defined]
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name not in ("log_time", "rerun.controls.RowId"):  # not needed, ns stamps
                out[chunk.entity_path][name] += batch.column(name).to_pylist()
    return out


def test_the_recording_has_every_body_both_feet_the_push_and_the_plots(
    run_dir: Path, recording: Path
) -> None:
    """Read back with Rerun's reader, the recording poses every body on simulated time, draws
    each foot's contact force and the push as arrows (the push only while it acts), and holds
    the run's plots, each line named with its unit."""
    from rerun.chunk import RrdReader

    reader = RrdReader(recording)
    columns = _columns(reader.store())
    model = mujoco.MjModel.from_xml_string(read_log(run_dir / "log.mcap").scene_xml)
    for name in body_names(model)[1:]:
        entity = "/" + body_entity(name)
        assert "Transform3D:translation" in columns[entity], entity
        assert "sim_time" in columns[entity]
    assert columns["/world"]["ViewCoordinates:xyz"]
    for foot in ("left_foot", "right_foot"):
        vectors = columns[f"/world/forces/contact/{foot}"]["Arrows3D:vectors"]
        standing = [v for v in vectors if v]
        assert standing and all(len(v) == 1 and v[0][2] > 0 for v in standing)  # pushes up
    push = columns["/world/forces/disturbance/torso"]
    times = [t.total_seconds() for t in push["sim_time"]]
    acting = [t for t, v in zip(times, push["Arrows3D:vectors"], strict=True) if v]
    assert acting and 0.1 - 1e-9 <= min(acting) and max(acting) < 0.3
    assert all(v[0][0] > 0 for v in push["Arrows3D:vectors"] if v)  # along +x
    lines = {
        entity: values["SeriesLines:names"][0]
        for entity, values in columns.items()
        if "SeriesLines:names" in values
    }
    assert lines["/plots/run/contact_force/left_foot"] == ["left_foot [N]"]
    assert lines["/plots/run/pelvis_height/z"] == ["z [m]"]
    assert lines["/plots/run/disturbance/torso"] == ["torso [N]"]
    # The posture controller declares no plots: its scalar signals are plotted.
    assert lines["/plots/posture/signals/posture_error"] == ["posture_error [?]"]
    assert len(columns["/plots/posture/signals/posture_error"]["Scalars:scalars"]) > 100
    assert columns["/verdict"]["TextDocument:text"][0][0].startswith("# pushed_stand")


def test_the_recording_opens_on_a_3d_view_the_plots_and_the_verdict(recording: Path) -> None:
    """The file carries a default blueprint: the 3D view following the pelvis, a time-series
    view per plot, the verdict and the events."""
    from rerun.chunk import RrdReader

    reader = RrdReader(recording)
    (blueprint,) = reader.blueprints()
    columns = _columns(reader.store(store=blueprint))
    views = {
        values["ViewBlueprint:display_name"][0][0]: values["ViewBlueprint:class_identifier"][0][0]
        for values in columns.values()
        if "ViewBlueprint:display_name" in values
    }
    assert views == {
        "robot": "3D",
        "verdict": "TextDocument",
        "events": "TextLog",
        "foot normal contact force [N]": "TimeSeries",
        "pelvis height [m]": "TimeSeries",
        "disturbance force [N]": "TimeSeries",
        "controller signals [?]": "TimeSeries",
    }


def test_an_existing_recording_is_kept_unless_forced(run_dir: Path, recording: Path) -> None:
    """A second export refuses to replace the file (exit 2, the file untouched); --force
    replaces it, and --out writes elsewhere."""
    before = recording.stat().st_mtime_ns
    result = runner.invoke(app, ["export", str(run_dir), "--rerun"])
    assert result.exit_code == 2 and "--force" in result.output
    assert "Traceback" not in result.output
    assert recording.stat().st_mtime_ns == before
    other = run_dir / "copy.rrd"
    assert (
        runner.invoke(
            app, ["export", str(run_dir / "log.mcap"), "--rerun", "--out", str(other)]
        ).exit_code
        == 0
    )
    assert other.stat().st_size > 0
    assert runner.invoke(app, ["export", str(run_dir), "--rerun", "--force"]).exit_code == 0
    assert not list(run_dir.glob(".*partial"))


def test_without_the_rerun_sdk_the_command_names_the_install(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without rerun-sdk, export exits 2 with one line naming the install command."""
    monkeypatch.setitem(sys.modules, "rerun", None)  # `import rerun` raises ImportError
    result = runner.invoke(app, ["export", str(tmp_path), "--rerun"])
    assert result.exit_code == 2
    assert INSTALL in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_export_asks_for_a_format() -> None:
    """export without a format flag exits 2 and names --rerun."""
    result = runner.invoke(app, ["export", "somewhere"])
    assert result.exit_code == 2 and "--rerun" in result.output


def test_the_centre_of_pressure_is_where_the_force_acts() -> None:
    """A force applied at a point p on the plane z = h (torque p × f about the origin) has
    its centre of pressure at p; with no normal force there is none."""
    p = np.array([0.3, -0.1, 0.05])
    f = np.array([20.0, -5.0, 400.0])
    wrench = np.array([[*f, *np.cross(p, f)], [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    cop = centre_of_pressure(wrench, np.array([p[2], 0.0]))
    np.testing.assert_allclose(cop[0], p, atol=1e-12)
    assert not np.isfinite(cop[1, :2]).any()


def test_a_declared_line_the_log_lacks_is_left_out_and_said(
    run_dir: Path, recording: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A declared line whose signal the log does not have (an older log) is left out with a
    note; the rest of the recording is written."""
    from walkrepro.present import rerun_export
    from walkrepro.present.plots import Plot, Series

    plot = Plot("p", "a plot", "m", (Series("/controller/signals.gone", "gone"),))
    monkeypatch.setattr(rerun_export, "_controller_plots", lambda log, controller: (plot,))
    result = runner.invoke(
        app, ["export", str(run_dir), "--rerun", "--out", str(run_dir / "older.rrd")]
    )
    assert result.exit_code == 0, result.output
    assert "skipped:" in result.output and "gone" in result.output
    assert (run_dir / "older.rrd").stat().st_size > 0


def test_an_older_rerun_sdk_is_named_with_the_upgrade(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Rerun SDK older than the export's API (0.41) exits 2 naming the upgrade."""
    rerun = pytest.importorskip("rerun", reason="the Rerun SDK is not installed")
    monkeypatch.setattr(rerun, "__version__", "0.30.1")
    result = runner.invoke(app, ["export", str(tmp_path), "--rerun"])
    assert result.exit_code == 2
    assert "0.30.1" in result.output and f"{INSTALL} --upgrade" in result.output
