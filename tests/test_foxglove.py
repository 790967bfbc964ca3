"""Foxglove messages of a run, decoded with Foxglove's published schemas."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader

from walkrepro import PROJECT_ROOT
from walkrepro.log import foxglove
from walkrepro.log.record import TOPIC_FRAMES, TOPIC_SCENE, TOPIC_SIGNALS, TOPIC_STATE, read_log
from walkrepro.runs.resolve import resolve_spec
from walkrepro.runs.runner import run
from walkrepro.specs.files import load_spec

LAYOUT = PROJECT_ROOT / "foxglove" / "walkrepro-layout.json"


@pytest.fixture(scope="module")
def stand_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 0.2 s run of stand_dyros_red (2 kHz control, 30 Hz frames)."""
    spec = resolve_spec(load_spec("stand_dyros_red", ["sim.duration=0.2"])).spec
    path = tmp_path_factory.mktemp("fox") / "log.mcap"
    assert run(spec, path).outcome == "complete"
    return path


def _raw(path: Path, topic: str) -> list:
    with open(path, "rb") as f:
        return [m for _, c, m in make_reader(f).iter_messages() if c.topic == topic]


def test_frames_are_every_bodys_pose_at_30_hz(stand_log: Path) -> None:
    """/frames decodes with foxglove.FrameTransforms: every body but the world, parent
    ``world``, pose = MuJoCo's kinematics of the logged state, stamped with the message's
    UTC log time; one message per 66 control ticks (33 ms, 30.3 Hz) at 2 kHz."""
    log = read_log(stand_log)
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    data = mujoco.MjData(model)
    states = {round(m["t"] * 1e9): m for m in log.messages(TOPIC_STATE)}
    origin = int(log.metadata["log_time_origin"])
    raw = _raw(stand_log, TOPIC_FRAMES)
    assert len(raw) == 7  # 0, 0.033, ..., 0.198 s
    assert [m.log_time - origin for m in raw] == [round(i * 0.033e9) for i in range(7)]
    names = foxglove.body_names(model)
    for message in raw:
        frames = FrameTransforms.FromString(message.data)
        assert [f.child_frame_id for f in frames.transforms] == names[1:]
        assert {f.parent_frame_id for f in frames.transforms} == {"world"}
        state = states[message.log_time - origin]
        data.qpos[:] = state["qpos"]
        mujoco.mj_kinematics(model, data)
        for i, frame in enumerate(frames.transforms, start=1):
            stamp = frame.timestamp.seconds * 10**9 + frame.timestamp.nanos
            assert stamp == message.log_time
            p, q = frame.translation, frame.rotation
            assert [p.x, p.y, p.z] == data.xpos[i].tolist()
            assert [q.w, q.x, q.y, q.z] == data.xquat[i].tolist()
    assert abs(origin / 1e9 - time.time()) < 3600  # wall-clock UTC


def test_scene_has_every_geom_on_its_bodys_frame(stand_log: Path) -> None:
    """/scene decodes with foxglove.SceneUpdate: one frame-locked entity per body that has
    geoms; boxes are cubes, spheres spheres, cylinders cylinders, a capsule a cylinder and
    two spheres; the floor a slab in the world frame."""
    model = mujoco.MjModel.from_xml_string(read_log(stand_log).scene_xml)
    (message,) = _raw(stand_log, TOPIC_SCENE)
    scene = SceneUpdate.FromString(message.data)
    names = foxglove.body_names(model)
    entities = {e.frame_id: e for e in scene.entities}
    assert set(entities) == {names[b] for b in model.geom_bodyid}
    assert all(e.frame_locked and e.id == e.frame_id for e in scene.entities)
    kinds = np.array(model.geom_type)
    g = mujoco.mjtGeom
    count = {k: int(np.sum(kinds == k)) for k in (g.mjGEOM_BOX, g.mjGEOM_SPHERE, g.mjGEOM_CAPSULE,
                                                  g.mjGEOM_CYLINDER, g.mjGEOM_PLANE)}  # fmt: skip
    assert sum(len(e.cubes) for e in scene.entities) == count[g.mjGEOM_BOX] + count[g.mjGEOM_PLANE]
    assert sum(len(e.cylinders) for e in scene.entities) == (
        count[g.mjGEOM_CYLINDER] + count[g.mjGEOM_CAPSULE]
    )
    assert sum(len(e.spheres) for e in scene.entities) == (
        count[g.mjGEOM_SPHERE] + 2 * count[g.mjGEOM_CAPSULE]
    )
    floor = entities["world"].cubes[0]
    assert floor.size.x == foxglove.FLOOR_SIZE and floor.pose.position.z < 0
    stamp = scene.entities[0].timestamp
    assert stamp.seconds * 10**9 + stamp.nanos == message.log_time


def test_a_log_decodes_without_walkrepro(stand_log: Path) -> None:
    """The public mcap reader with mcap-protobuf-support decodes every topic, in a process
    that never imports walkrepro."""
    script = Path(__file__).with_name("decode_without_walkrepro.py")
    result = subprocess.run(
        [sys.executable, str(script), str(stand_log)], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    assert "/frames: 7 messages" in result.stdout and "log_format 2" in result.stdout


def test_frames_come_at_least_30_times_a_second() -> None:
    """Whatever the control rate, frames are at most 1/30 s apart, on whole control ticks."""
    for period in (0.0005, 0.001, 0.002, 0.004, 0.05):
        every = foxglove.frame_every(period)
        assert every >= 1 and (every * period <= 1 / 30 + 1e-12 or every == 1)
        assert (every + 1) * period > 1 / 30


def test_layout_is_a_foxglove_layout_of_the_logs_topics() -> None:
    """The shipped layout has a 3D panel showing /scene and plots of existing topics."""
    layout = json.loads(LAYOUT.read_text())
    panels = layout["configById"]
    assert set(re.findall(r'"([A-Za-z0-9]+![A-Za-z_]+)"', json.dumps(layout["layout"]))) <= set(
        panels
    )
    assert panels["3D!robot"]["topics"] == {"/scene": {"visible": True}}
    topics = {p["value"].split(".")[0] for c in panels.values() for p in c.get("paths", [])}
    assert topics == {TOPIC_SIGNALS, "/sim/contacts", TOPIC_STATE}


@pytest.mark.slow
def test_layout_plots_signals_the_controllers_log(tmp_path: Path) -> None:
    """Every /controller/signals name in the layout is logged by one of the three papers'
    controllers."""
    layout = json.loads(LAYOUT.read_text())
    wanted = {
        re.match(r"/controller/signals\.(\w+)", p["value"]).group(1)  # type: ignore[union-attr]
        for c in layout["configById"].values()
        for p in c.get("paths", [])
        if p["value"].startswith(TOPIC_SIGNALS)
    }
    logged: set[str] = set()
    for name in ("forward_walk", "in_place", "walk_flat_kist"):
        spec = resolve_spec(load_spec(name, ["sim.duration=0.7"])).spec
        path = tmp_path / f"{name}.mcap"
        run(spec, path)
        for message in read_log(path).messages(TOPIC_SIGNALS):
            logged.update(message)
    assert wanted <= logged, wanted - logged
