"""Videos of runs (``walkrepro render RUN --video``): frames, arrows, overlays, the MP4."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.errors import WalkreproError
from walkrepro.present import video
from walkrepro.runtime import gl

NO_GL = gl.INSTALL_HINT.format(tried="probed at collection")


def test_frame_times_cover_the_run_at_the_frame_rate() -> None:
    """Frames fall every 1/fps of simulated time, from 0 up to the last logged time."""
    assert len(video.frame_times(1.0, 30)) == 31
    assert len(video.frame_times(0.99, 30)) == 30
    np.testing.assert_allclose(video.frame_times(0.1, 30), [0, 1 / 30, 2 / 30, 3 / 30])


def test_each_robot_body_gets_its_own_colour_and_the_floor_keeps_its_own() -> None:
    """Neighbouring links differ in colour; geoms outside the robot (the floor) are untouched."""
    model = mujoco.MjModel.from_xml_string(
        """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 1" rgba="1 1 1 1"/>
        <body name="pelvis"><freejoint/><geom type="sphere" size="0.1"/>
          <body name="thigh"><joint type="hinge"/><geom type="capsule" size="0.05 0.2"/>
          </body></body></worldbody></mujoco>"""
    )
    video.colour_bodies(model, model.body("pelvis").id)
    pelvis, thigh = model.geom_rgba[1], model.geom_rgba[2]
    assert not np.allclose(pelvis, thigh)
    np.testing.assert_allclose(model.geom_rgba[0], [1, 1, 1, 1])
    np.testing.assert_allclose(pelvis[:3], video.PALETTE[0])


def test_a_disturbance_is_an_arrow_ending_at_the_pushed_body() -> None:
    """A pushed body gets one arrow pointing along the force to its centre of mass; no force,
    no arrow."""
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="torso" pos="0 0 1"><freejoint/>'
        '<geom type="box" size="0.1 0.1 0.1"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    scene = mujoco.MjvScene(model, maxgeom=10)
    torso = model.body("torso").id
    video._arrows(data, {torso: np.array([60.0, 0.0, 0.0])})(scene)
    assert scene.ngeom == 1
    arrow = scene.geoms[0]
    assert arrow.type == mujoco.mjtGeom.mjGEOM_ARROW
    # The arrow starts 0.6 m behind the body (60 N at 0.01 m/N) and points along +x.
    np.testing.assert_allclose(arrow.pos, [-0.6, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(arrow.mat[:, 2], [1.0, 0.0, 0.0], atol=1e-9)
    empty = mujoco.MjvScene(model, maxgeom=10)
    video._arrows(data, {torso: np.zeros(3)})(empty)
    assert empty.ngeom == 0


@pytest.mark.skipif(not gl.available(), reason=NO_GL)
def test_a_drawn_arrow_ends_at_the_pushed_body() -> None:
    """In the rendered image, the red arrow spans from its tail to the body's centre of mass
    (seen from the side, 1 m of force arrow over the image's x axis)."""
    from walkrepro.present.render import Offscreen

    model = mujoco.MjModel.from_xml_string(
        '<mujoco><visual><global offwidth="640" offheight="360"/></visual><statistic extent="2"/>'
        '<worldbody><light pos="0 -2 3" dir="0 1 -1"/><body name="b" pos="0.3 0 1"><freejoint/>'
        '<geom type="sphere" size="0.001" rgba="0 0 0 0"/></body></worldbody></mujoco>'
    )
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth, camera.elevation, camera.distance = 90.0, 0.0, 3.0
    camera.lookat[:] = [0.0, 0.0, 1.0]
    body = model.body("b").id
    with Offscreen(model, 640, 360, shadows=False) as view:
        image = view.render(data, camera, video._arrows(data, {body: np.array([60.0, 0, 0])}))
    r, g, b = (image[:, :, i].astype(int) for i in range(3))
    red = np.argwhere((r > 40) & (r > 2 * g) & (r > 2 * b))
    assert len(red)
    # Pinhole projection of x at depth 3 m with MuJoCo's 45° vertical field of view.
    px_per_m = 360 / (2 * 3.0 * np.tan(np.radians(22.5)))
    tail_px, tip_px = 320 + (0.3 - 0.6) * px_per_m, 320 + 0.3 * px_per_m
    assert red[:, 1].min() == pytest.approx(tail_px, abs=4)
    assert red[:, 1].max() == pytest.approx(tip_px, abs=4)


def test_the_overlay_names_the_controller_state_from_its_events() -> None:
    """The E-FSM's state is its last transition; a fall is shown for EVENT_SHOWN seconds only."""
    events = [
        {"t": 0.1, "kind": "fsm", "from": "DS", "to": "SSD"},
        {"t": 0.1, "kind": "support", "foot": "left", "step": 1},
        {"t": 0.3, "kind": "fsm", "from": "SSD", "to": "SSA"},
        {"t": 0.5, "kind": "fall", "reason": "pelvis low"},
    ]
    labels, values = video._state_text(events, 0.2)
    assert labels.splitlines() == ["FSM state", "footstep"]
    assert values.splitlines() == ["SSD", "step 1 (left support)"]
    assert "fall pelvis low" in video._state_text(events, 0.6)[1]
    assert "fall" not in video._state_text(events, 0.5 + video.EVENT_SHOWN + 0.1)[1]
    assert video._state_text([], 1.0) == ("", "")


def test_an_odd_video_size_is_refused_before_rendering(tmp_path: Path) -> None:
    """H.264 in yuv420p needs even sizes: an odd one is a user error, not an encoder crash."""
    with pytest.raises(WalkreproError, match="even width and height"):
        video.render_video(tmp_path / "missing.mcap", tmp_path / "v.mp4", width=641)


@pytest.mark.skipif(not gl.available(), reason=NO_GL)
def test_render_video_writes_a_playable_mp4_of_the_whole_run(tmp_path: Path) -> None:
    """`walkrepro render RUN --video` writes an H.264 MP4 whose reader reports one frame per
    1/fps of simulated time and the matching duration; every frame decodes."""
    import imageio_ffmpeg

    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.runs.runner import run
    from walkrepro.specs.files import load_spec

    spec = resolve_spec(load_spec("stand_dyros_red", ["sim.duration=0.5"])).spec
    log = tmp_path / "log.mcap"
    run(spec, log)
    result = CliRunner().invoke(app, ["render", str(log), "--video", "--fps", "20"])
    assert result.exit_code == 0, result.output
    mp4 = tmp_path / video.VIDEO_FILE
    expected = len(video.frame_times(0.5, 20))  # 11 frames: t = 0, 0.05, ..., 0.5 s
    assert f"{expected} frames" in result.output
    reader = imageio_ffmpeg.read_frames(str(mp4))
    meta = next(reader)
    assert meta["codec"].startswith("h264")
    assert meta["size"] == (video.DEFAULT_WIDTH, video.DEFAULT_HEIGHT)
    assert meta["fps"] == pytest.approx(20)
    frames = [np.frombuffer(f, np.uint8) for f in reader]
    assert len(frames) == expected
    assert all(f.size == video.DEFAULT_WIDTH * video.DEFAULT_HEIGHT * 3 for f in frames)
    assert np.ptp(frames[0]) > 50  # a picture, not a blank frame
    n, seconds = imageio_ffmpeg.count_frames_and_secs(str(mp4))
    assert n == expected
    assert seconds == pytest.approx(expected / 20, abs=0.051)


@pytest.mark.skipif(not gl.available(), reason=NO_GL)
def test_walkrepro_run_writes_the_video_and_says_where_it_is(tmp_path: Path) -> None:
    """`walkrepro run` leaves video.mp4 in the run directory next to figures/ and prints both."""
    args = ["run", "stand_dyros_red", "--set", "sim.duration=0.2", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    (run_dir,) = (tmp_path / "stand_dyros_red").iterdir()
    assert (run_dir / video.VIDEO_FILE).stat().st_size > 1000
    assert f"video: {run_dir / video.VIDEO_FILE}" in result.output
    assert f"figures: {run_dir / 'figures'}" in result.output


def test_without_gl_a_run_keeps_everything_but_the_video(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With no OpenGL backend the run still succeeds, with its figures, and a one-line note
    says why there is no video."""

    def unavailable() -> type:
        raise gl.RenderingUnavailable(gl.INSTALL_HINT.format(tried="none (test)"))

    monkeypatch.setattr(gl, "gl_context_class", unavailable)
    args = ["run", "stand_dyros_red", "--set", "sim.duration=0.2", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    (run_dir,) = (tmp_path / "stand_dyros_red").iterdir()
    assert not (run_dir / video.VIDEO_FILE).exists()
    assert (run_dir / "figures").is_dir()
    assert "no video: Rendering needs an OpenGL backend" in result.output


@pytest.mark.skipif(not gl.available(), reason=NO_GL)
def test_contact_forces_can_be_drawn(tmp_path: Path) -> None:
    """With contact forces on, the feet's contact arrows change the picture of a standing robot."""
    from walkrepro.runs.resolve import resolve_spec
    from walkrepro.runs.runner import run
    from walkrepro.specs.files import load_spec

    spec = resolve_spec(load_spec("stand_dyros_red", ["sim.duration=0.1"])).spec
    log = tmp_path / "log.mcap"
    run(spec, log)
    plain = video.render_video(log, tmp_path / "plain.mp4", fps=10)
    forces = video.render_video(log, tmp_path / "forces.mp4", fps=10, contact_forces=True)
    assert plain.n_frames == forces.n_frames == 2
    import imageio_ffmpeg

    def last_frame(path: Path) -> np.ndarray:
        return np.frombuffer(list(imageio_ffmpeg.read_frames(str(path)))[-1], np.uint8)

    difference = np.abs(last_frame(plain.path).astype(int) - last_frame(forces.path))
    assert (difference > 60).sum() > 50
