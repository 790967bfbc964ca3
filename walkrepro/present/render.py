"""Snapshot strips and videos of a run, rendered headless from the log.

Rendering reads only the log: the scene XML, the logged states, the applied disturbance
wrenches and the controller's events. It is also the quickest way to check by eye that a
robot really walks. The OpenGL backend is chosen here, when something is rendered, never at
import (:mod:`walkrepro.runtime.gl`). The video itself is written by :mod:`walkrepro.present.video`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from walkrepro.errors import WalkreproError  # noqa: E402
from walkrepro.log import record
from walkrepro.runtime import gl  # noqa: E402


def render_strip(
    log_path: Path, times: list[float], out: Path, width: int, height: int, partial: bool = False
) -> Path:
    """Render the logged state nearest to each time and save the frames side by side.

    The camera looks at the pelvis from the robot's left side (the walking direction goes
    to the right of the image), so forward progress and foot clearance are both visible.
    A cut or damaged log is refused unless ``partial`` (the title then says ``PARTIAL``).
    """
    if not times:
        raise WalkreproError("--at: give at least one time [s] to render, e.g. --at 0,2,4.")
    from walkrepro.log.integrity import read_checked_log

    log, found = read_checked_log(log_path, partial)
    states = log.messages(record.TOPIC_STATE)
    if not states:
        raise WalkreproError(f"{log_path}: the log holds no /sim/state messages to render.")
    t = np.array([s["t"] for s in states])
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth, camera.elevation, camera.distance = 90.0, -15.0, 3.2
    frames, shown = [], []
    pelvis = model.body("pelvis").id
    with Offscreen(model, width, height) as view:
        for when in times:
            i = int(np.argmin(np.abs(t - when)))
            data.qpos[:] = states[i]["qpos"]
            data.qvel[:] = states[i]["qvel"]
            mujoco.mj_forward(model, data)
            camera.lookat[:] = [
                data.xpos[pelvis, 0],
                data.xpos[pelvis, 1],
                0.6 * data.xpos[pelvis, 2],
            ]
            frames.append(view.render(data, camera))
            shown.append(float(t[i]))

    fig, axes = plt.subplots(1, len(frames), figsize=(2.4 * len(frames), 2.4 * height / width))
    for ax, frame, ti in zip(np.atleast_1d(axes), frames, shown, strict=True):
        ax.imshow(frame)
        ax.set_title(f"t = {ti:.2f} s", fontsize=9)
        ax.axis("off")
    spec_name = log.metadata.get("experiment", log_path.stem)
    outcome = "partial" if not found.whole else log.metadata.get("outcome", "unknown")
    head = f"{spec_name} — snapshots (outcome: {outcome})"
    fig.suptitle(f"{head}\n{found.short()}" if not found.whole else head)
    fig.tight_layout()
    from walkrepro.runtime import outdir

    outdir.check_file(out, force=True)  # a directory or a read-only place: a clean error
    try:
        with outdir.writing_file(out) as partial:
            fig.savefig(partial, dpi=120)
    finally:
        plt.close(fig)
    return out


class Offscreen:
    """An offscreen MuJoCo render target on the backend :func:`walkrepro.runtime.gl.gl_context_class`
    chose (MuJoCo's public ``mjr_*`` API, so the backend need not be the one MuJoCo picked
    when it was imported)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        font_scale: int = mujoco.mjtFontScale.mjFONTSCALE_150,
        shadows: bool = True,
    ) -> None:
        """Args: ``shadows`` False also drops reflections (three times faster in software GL)."""
        self._model = model
        self._viewport = mujoco.MjrRect(0, 0, width, height)
        self._context = gl.gl_context_class()(width, height)
        self._context.make_current()
        self.scene = mujoco.MjvScene(model, maxgeom=10000)
        if not shadows:
            self.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0
            self.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
        self._mjr = mujoco.MjrContext(model, font_scale)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._mjr)
        self.option, self._perturb = mujoco.MjvOption(), mujoco.MjvPerturb()
        self._pixels = np.empty((height, width, 3), dtype=np.uint8)

    def render(
        self,
        data: mujoco.MjData,
        camera: mujoco.MjvCamera,
        decorate: Callable[[mujoco.MjvScene], None] | None = None,
        overlays: Sequence[tuple[int, str, str]] = (),
    ) -> np.ndarray:
        """One RGB frame (height x width x 3, uint8, top row first).

        Args:
            data: the state to draw (kinematics already computed).
            camera: the camera.
            decorate: adds geoms (e.g. arrows) to the scene after MuJoCo filled it.
            overlays: text boxes ``(mjtGridPos, left column, right column)``.
        """
        mujoco.mjv_updateScene(
            self._model,
            data,
            self.option,
            self._perturb,
            camera,
            mujoco.mjtCatBit.mjCAT_ALL,
            self.scene,
        )
        if decorate is not None:
            decorate(self.scene)
        mujoco.mjr_render(self._viewport, self.scene, self._mjr)
        for gridpos, left, right in overlays:
            mujoco.mjr_overlay(
                mujoco.mjtFont.mjFONT_NORMAL, gridpos, self._viewport, left, right, self._mjr
            )
        mujoco.mjr_readPixels(self._pixels, None, self._viewport, self._mjr)
        return np.flipud(self._pixels).copy()

    def __enter__(self) -> Offscreen:
        return self

    def __exit__(self, *exc: object) -> None:
        self._mjr.free()
        self._context.free()
