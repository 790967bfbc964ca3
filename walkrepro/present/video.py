"""A video of a run, rendered headless from its log: ``walkrepro render RUN --video``.

Like the snapshot strip (:mod:`walkrepro.present.render`), the video reads only the log: the scene
XML, the logged states (drawn by setting ``qpos``), the disturbance wrenches applied at each
physics step (drawn as arrows) and the controller's events (its state, overlaid as text).
Frames are taken at a fixed rate of simulated time, so the video plays at real time. It is
encoded as H.264 by the ffmpeg binary that the ``imageio-ffmpeg`` wheel ships, so no system
encoder is needed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from walkrepro.errors import WalkreproError
from walkrepro.log import record
from walkrepro.present.render import Offscreen

#: The video's file name in a run directory and in a committed reference.
VIDEO_FILE = "video.mp4"
#: Frames per second of simulated time (real-time playback).
DEFAULT_FPS = 30
#: Frame size in [px]: small enough that a headline run stays well under 1 MB.
DEFAULT_WIDTH, DEFAULT_HEIGHT = 640, 360
#: x264's constant rate factor: 23 is its default; higher is smaller and blurrier.
DEFAULT_CRF = 30
#: Colours of the robot's links (RGB in [0, 1]), one per body in turn (Okabe-Ito, colour-blind
#: safe, without black).
PALETTE: tuple[tuple[float, float, float], ...] = (
    (0.90, 0.62, 0.00),
    (0.34, 0.71, 0.91),
    (0.00, 0.62, 0.45),
    (0.94, 0.89, 0.26),
    (0.00, 0.45, 0.70),
    (0.84, 0.37, 0.00),
    (0.80, 0.47, 0.65),
    (0.60, 0.60, 0.60),
)
#: Arrow length per newton of disturbance force [m/N], and its bounds [m].
ARROW_SCALE, ARROW_MIN, ARROW_MAX = 0.01, 0.15, 0.6
#: Arrow shaft width [m] and colour (RGBA).
ARROW_WIDTH, ARROW_RGBA = 0.025, (0.85, 0.1, 0.1, 1.0)
#: MuJoCo's renderer draws an arrow geom over half of the length ``mjv_connector`` gives it
#: (measured with MuJoCo 4.0; cylinders and capsules span their connector exactly), so the
#: length is doubled to make the arrow end at the pushed body (tests/test_render.py checks it
#: in pixels).
ARROW_DRAWN_FRACTION = 0.5
#: Camera: distance per metre of the robot's initial height (its highest geom), so a 0.9 m
#: and a 1.4 m robot fill the frame alike (MuJoCo's 45° field of view then spans about 1.5
#: heights); elevation [deg]; the look-at height as a fraction of the robot's height (fixed,
#: so a fall is seen as a drop).
CAMERA_DISTANCE, CAMERA_ELEVATION, LOOKAT_HEIGHT = 1.8, -8.0, 0.5
#: How long an event without a lasting state (a fall, impedance switched on) stays shown [s].
EVENT_SHOWN = 1.0


@dataclass(frozen=True)
class VideoInfo:
    """A written video.

    Attributes:
        path: the MP4 file.
        n_frames: frames written.
        fps: frames per second of simulated time.
        duration: length in [s] (``n_frames / fps``).
    """

    path: Path
    n_frames: int
    fps: int
    duration: float


def frame_times(sim_time: float, fps: int) -> np.ndarray:
    """Simulated times of the frames: ``k / fps`` for every ``k`` with ``k / fps ≤ sim_time``.

    Args:
        sim_time: last logged time [s].
        fps: frames per second.
    """
    n = int(math.floor(sim_time * fps + 1e-9)) + 1
    return np.arange(n) / fps


def colour_bodies(model: mujoco.MjModel, root_body: int) -> None:
    """Give each body of the robot (the tree of ``root_body``) its own colour from
    :data:`PALETTE`, keeping each geom's alpha (hidden collision geoms stay hidden)."""
    robot = [b for b in range(model.nbody) if model.body_rootid[b] == model.body_rootid[root_body]]
    colour = {body: PALETTE[i % len(PALETTE)] for i, body in enumerate(robot)}
    for g in range(model.ngeom):
        body = int(model.geom_bodyid[g])
        if body in colour:
            model.geom_matid[g] = -1  # a material's colour would override the geom's
            model.geom_rgba[g, :3] = colour[body]


def robot_height(model: mujoco.MjModel, data: mujoco.MjData, root_body: int) -> float:
    """Height [m] of the robot's highest visible geom (bounding sphere) above z = 0, for a
    state whose kinematics are computed."""
    root = model.body_rootid[root_body]
    tops = [
        data.geom_xpos[g, 2] + model.geom_rbound[g]
        for g in range(model.ngeom)
        if model.body_rootid[model.geom_bodyid[g]] == root and model.geom_rgba[g, 3] > 0
    ]
    return float(max(tops)) if tops else float(data.xpos[root_body, 2])


@dataclass(frozen=True)
class _Push:
    """The disturbance forces applied at one physics step: body id → force in O_world [N]."""

    t: float
    forces: Mapping[int, np.ndarray]


def _pushes(log: record.Log, model: mujoco.MjModel) -> list[_Push]:
    """Every physics step with a non-zero disturbance force (the ``xfrc`` of ``/sim/inputs``)."""
    out = []
    for message in log.messages(record.TOPIC_INPUTS):
        forces = {
            model.body(body).id: np.asarray(wrench[:3], dtype=float)
            for body, wrench in message["xfrc"].items()
            if np.any(np.asarray(wrench[:3]) != 0.0)
        }
        if forces:
            out.append(_Push(message["step"] * model.opt.timestep, forces))
    return out


def _state_text(events: Sequence[Mapping[str, object]], t: float) -> tuple[str, str]:
    """The controller's state at ``t`` from its logged events: ``(label, value)`` columns.

    The E-FSM logs its transitions (``fsm``: DS, SSD, SSA) and supports; the time-projection
    controller its steps (``phase``); other events (impedance switched on, a fall) are shown
    for :data:`EVENT_SHOWN` seconds.
    """
    state, step, recent = "", "", []
    for e in events:
        te = float(e["t"])  # type: ignore[arg-type]
        if te > t:
            break
        kind = e.get("kind")
        if kind == "fsm":
            state = str(e["to"])
        elif kind == "support":
            step = f"step {e['step']} ({e['foot']} support)"
        elif kind == "phase":
            step = f"step {e['step']} ({e['swing']} swing)"
        elif kind not in ("disturbance_on", "disturbance_off") and t - te <= EVENT_SHOWN:
            what = str(kind).replace("_", " ")
            where = e.get("foot") or e.get("reason") or ""
            recent.append(f"{what} {where}".strip())
    labels, values = [], []
    if state:
        labels.append("FSM state")
        values.append(state)
    if step:
        labels.append("footstep")
        values.append(step)
    for text in recent[-2:]:
        labels.append("event")
        values.append(text)
    return "\n".join(labels), "\n".join(values)


def _pelvis(model: mujoco.MjModel) -> int:
    """The pelvis body, else the first body with a free joint (the floating base)."""
    try:
        return model.body("pelvis").id
    except KeyError:
        free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
        if not free:
            raise WalkreproError("the scene has no pelvis and no floating base to follow") from None
        return int(model.jnt_bodyid[free[0]])


def _arrows(
    data: mujoco.MjData, forces: Mapping[int, np.ndarray]
) -> Callable[[mujoco.MjvScene], None]:
    """Adds one arrow per pushed body, pointing along the force and ending at the body's
    centre of mass, where ``xfrc_applied`` acts."""

    def decorate(scene: mujoco.MjvScene) -> None:
        for body, force in forces.items():
            magnitude = float(np.linalg.norm(force))
            if magnitude == 0.0 or scene.ngeom >= scene.maxgeom:
                continue
            length = min(max(ARROW_SCALE * magnitude, ARROW_MIN), ARROW_MAX)  # [m]
            tip = data.xipos[body].copy()
            tail = tip - force / magnitude * length
            geom = scene.geoms[scene.ngeom]
            mujoco.mjv_initGeom(
                geom,
                mujoco.mjtGeom.mjGEOM_ARROW,
                np.zeros(3),
                np.zeros(3),
                np.eye(3).ravel(),
                np.array(ARROW_RGBA, dtype=np.float32),
            )
            mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, ARROW_WIDTH, tail, tip)
            geom.size[2] = length / ARROW_DRAWN_FRACTION
            scene.ngeom += 1

    return decorate


def _frames(
    log: record.Log,
    times: np.ndarray,
    width: int,
    height: int,
    contact_forces: bool,
    note: str = "",
) -> Iterator[np.ndarray]:
    """The frames at ``times`` (RGB, height x width x 3); ``note`` is a second title line
    (a damaged log's ``PARTIAL: ...``)."""
    states = log.arrays(record.TOPIC_STATE)
    t_state = states["t"]
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    # No multisampling: 2.4x faster in software GL (20 ms a frame at 640x360), and H.264 at
    # this size smooths the edges anyway.
    model.vis.quality.offsamples = 0
    pelvis = _pelvis(model)
    colour_bodies(model, pelvis)
    data = mujoco.MjData(model)
    pushes = _pushes(log, model)
    push_t = np.array([p.t for p in pushes])
    events = sorted(log.messages(record.TOPIC_EVENTS), key=lambda e: float(e["t"]))
    ctrl = log.arrays(record.TOPIC_INPUTS, ("step", "ctrl")) if contact_forces else {}
    dt = model.opt.timestep
    title = log.metadata.get("experiment", log.path.stem) + (f"\n{note}" if note else "")

    data.qpos[:] = states["qpos"][0]
    mujoco.mj_kinematics(model, data)
    # The side camera: perpendicular to the pelvis's initial heading, walking to the right.
    heading = math.degrees(math.atan2(data.xmat[pelvis, 3], data.xmat[pelvis, 0]))
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth, camera.elevation = heading + 90.0, CAMERA_ELEVATION
    tall = robot_height(model, data, pelvis)  # [m]
    camera.distance = CAMERA_DISTANCE * tall
    lookat_z = LOOKAT_HEIGHT * tall

    with Offscreen(
        model, width, height, mujoco.mjtFontScale.mjFONTSCALE_100, shadows=False
    ) as view:
        if contact_forces:
            view.option.flags[mujoco.mjtVisFlag.mjVIS_CONTACTFORCE] = True
        for t in times:
            i = min(int(np.searchsorted(t_state, t - 1e-9)), len(t_state) - 1)
            data.qpos[:] = states["qpos"][i]
            data.qvel[:] = states["qvel"][i]
            if "act" in states and model.na:
                data.act[:] = states["act"][i]
            if contact_forces and ctrl:
                k = min(int(np.searchsorted(ctrl["step"], round(t / dt))), len(ctrl["step"]) - 1)
                data.ctrl[:] = ctrl["ctrl"][k]
                mujoco.mj_forward(model, data)
            else:
                mujoco.mj_kinematics(model, data)
                mujoco.mj_comPos(model, data)
            camera.lookat[:] = [data.xpos[pelvis, 0], data.xpos[pelvis, 1], lookat_z]
            # The push applied during this frame's time step (a log holds it per step).
            forces: Mapping[int, np.ndarray] = {}
            if len(push_t):
                j = int(np.searchsorted(push_t, t - 0.5 * dt))
                if j < len(push_t) and abs(push_t[j] - t) <= 0.5 * dt + 1e-12:
                    forces = pushes[j].forces
            push_text = ", ".join(
                f"{model.body(b).name} {np.linalg.norm(f):.0f} N" for b, f in forces.items()
            )
            labels, values = _state_text(events, t)
            overlays = [
                (mujoco.mjtGridPos.mjGRID_TOPLEFT, title, ""),
                (mujoco.mjtGridPos.mjGRID_TOPRIGHT, "t", f"{t:6.2f} s"),
            ]
            if labels or push_text:
                labels = "\n".join(x for x in (labels, "push" if push_text else "") if x)
                values = "\n".join(x for x in (values, push_text) if x)
                overlays.append((mujoco.mjtGridPos.mjGRID_BOTTOMLEFT, labels, values))
            yield view.render(data, camera, _arrows(data, forces) if forces else None, overlays)


def render_video(
    log_path: Path,
    out: Path,
    fps: int = DEFAULT_FPS,
    width: int = DEFAULT_WIDTH,
    height: int = DEFAULT_HEIGHT,
    contact_forces: bool = False,
    crf: int = DEFAULT_CRF,
    stop: Callable[[], bool] | None = None,
    partial: bool = False,
) -> VideoInfo:
    """Render the whole run to an H.264 MP4 that plays at real time.

    A side camera follows the pelvis; each link has its own colour; disturbance forces are
    red arrows ending at the pushed body's centre of mass; the time, the controller's state
    and the push are overlaid.

    Args:
        log_path: the run's ``log.mcap``.
        out: the MP4 to write (its directory is created).
        fps: frames per second of simulated time.
        width: frame width [px] (even).
        height: frame height [px] (even).
        contact_forces: also draw contact forces (MuJoCo's ``mjVIS_CONTACTFORCE``; the
            logged ``ctrl`` is set so the forces are the run's).
        crf: x264's constant rate factor (quality; higher is smaller).
        stop: polled between frames; when it returns true the video is abandoned
            (``KeyboardInterrupt``, the partial file removed, ``out`` untouched).
        partial: render a cut or damaged log for what it holds (each frame's title then
            says ``PARTIAL``); without it such a log is refused
            (:class:`walkrepro.log.integrity.DamagedLogError`).

    Raises:
        WalkreproError: the log holds no states, or the size is odd.
        RenderingUnavailable: no OpenGL backend works here.
    """
    import imageio_ffmpeg

    if width % 2 or height % 2 or width <= 0 or height <= 0:
        raise WalkreproError(f"video size {width}x{height}: H.264 needs an even width and height.")
    if fps <= 0:
        raise WalkreproError(f"--fps {fps}: needs a positive number of frames per second.")
    from walkrepro.log.integrity import read_checked_log

    log, found = read_checked_log(log_path, partial)
    t_state = log.arrays(record.TOPIC_STATE, ("t",)).get("t")
    if t_state is None or not len(t_state):
        raise WalkreproError(f"{log_path}: the log holds no /sim/state messages to render.")
    times = frame_times(float(t_state[-1]), fps)
    from walkrepro.runtime import outdir

    outdir.check_file(out, force=True)  # a directory or a read-only place: a clean error
    with outdir.writing_file(out) as partial:
        writer = imageio_ffmpeg.write_frames(
            str(partial),
            (width, height),
            fps=fps,
            codec="libx264",
            quality=None,
            macro_block_size=2,
            pix_fmt_out="yuv420p",
            ffmpeg_log_level="error",
            output_params=[
                *("-crf", str(crf), "-preset", "slow", "-movflags", "+faststart", "-f", "mp4")
            ],
        )
        writer.send(None)  # start the encoder
        n = 0
        try:
            for frame in _frames(log, times, width, height, contact_forces, found.short()):
                if stop is not None and stop():
                    raise KeyboardInterrupt
                writer.send(np.ascontiguousarray(frame))
                n += 1
        finally:
            writer.close()
    return VideoInfo(out, n, fps, n / fps)


def render_run_video(
    log_path: Path, run_dir: Path, stop: Callable[[], bool] | None = None
) -> Path | None:
    """The video of a finished run, ``run_dir/video.mp4``, if this machine can render.

    Without an OpenGL backend the run keeps everything else: a one-line note goes to stderr
    and None is returned (rendering is optional; the install hint is in the note). ``stop``
    is polled between frames; once true, the video is abandoned (``KeyboardInterrupt``).
    """
    import sys

    from walkrepro.runtime.gl import RenderingUnavailable

    try:
        return render_video(log_path, run_dir / VIDEO_FILE, stop=stop).path
    except RenderingUnavailable as exc:
        print(f"no video: {exc}", file=sys.stderr)
        return None
