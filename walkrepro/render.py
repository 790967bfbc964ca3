"""Snapshot strips of a run, rendered headless from the log (like the papers' photo strips).

Rendering reads only the log: the scene XML and the logged states. It is also the quickest
way to check by eye that a robot really walks.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from walkrepro import record  # noqa: E402
from walkrepro.errors import WalkreproError  # noqa: E402


def render_strip(log_path: Path, times: list[float], out: Path, width: int, height: int) -> Path:
    """Render the logged state nearest to each time and save the frames side by side.

    The camera looks at the pelvis from the robot's left side (the walking direction goes
    to the right of the image), so forward progress and foot clearance are both visible.
    """
    log = record.read_log(log_path)
    states = log.messages(record.TOPIC_STATE)
    if not states:
        raise WalkreproError(f"{log_path}: the log holds no /sim/state messages to render.")
    t = np.array([s["t"] for s in states])
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    data = mujoco.MjData(model)
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # backend missing: say how to get one
        raise WalkreproError(
            f"cannot create an OpenGL context for rendering ({exc}). Install OSMesa "
            "(apt-get install libosmesa6) and set MUJOCO_GL=osmesa, or use MUJOCO_GL=egl."
        ) from None
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth, camera.elevation, camera.distance = 90.0, -15.0, 3.2
    frames, shown = [], []
    pelvis = model.body("pelvis").id
    for when in times:
        i = int(np.argmin(np.abs(t - when)))
        data.qpos[:] = states[i]["qpos"]
        data.qvel[:] = states[i]["qvel"]
        mujoco.mj_forward(model, data)
        camera.lookat[:] = [data.xpos[pelvis, 0], data.xpos[pelvis, 1], 0.6 * data.xpos[pelvis, 2]]
        renderer.update_scene(data, camera)
        frames.append(renderer.render().copy())
        shown.append(float(t[i]))
    renderer.close()

    fig, axes = plt.subplots(1, len(frames), figsize=(2.4 * len(frames), 2.4 * height / width))
    for ax, frame, ti in zip(np.atleast_1d(axes), frames, shown, strict=True):
        ax.imshow(frame)
        ax.set_title(f"t = {ti:.2f} s", fontsize=9)
        ax.axis("off")
    spec_name = log.metadata.get("experiment", log_path.stem)
    fig.suptitle(f"{spec_name} — snapshots (outcome: {log.metadata.get('outcome', 'unknown')})")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
