"""The sensor model: what the controller reads, its seeded imperfections, and its delay."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from walkrepro.runs.resolve import resolve_spec
from walkrepro.runs.runner import _set_home
from walkrepro.sim.contact_reader import ContactReader
from walkrepro.sim.robot import load_robot
from walkrepro.sim.sensors import SensorModel, SensorSnapshot
from walkrepro.sim.world import build_scene
from walkrepro.specs.files import load_spec
from walkrepro.specs.models import SensorsSpec

G = 9.81


def standing(robot_name: str, experiment: str):  # noqa: ANN201 - (robot, model, data)
    """A robot settled on the floor for 0.2 s with its home servo targets / zero torques."""
    spec = resolve_spec(load_spec(experiment)).spec
    robot = load_robot(robot_name)
    model = build_scene(robot, spec).model
    data = mujoco.MjData(model)
    _set_home(robot, model, data)
    for _ in range(400):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    return robot, model, data


@pytest.fixture(scope="module")
def coman():  # noqa: ANN201
    return standing("coman", "stand_coman")


def test_exact_reading_matches_the_simulator(coman) -> None:  # noqa: ANN001
    """Without imperfections the snapshot is the simulator's state: link-side encoders (motor +
    spring for series-elastic joints), IMU, base state, and F/T as the foot pushes on the leg."""
    robot, model, data = coman
    snap = SensorModel(robot, model, SensorsSpec(base_state=True), 0.002, 0).read(model, data)
    link = robot.link_joint_qpos_adr(model)
    assert np.array_equal(snap.joint_pos, link.link_values(data.qpos))
    assert np.array_equal(snap.base_pos, data.qpos[:3]) and snap.t == data.time
    assert np.array_equal(snap.joint_vel, robot.link_joint_qvel_adr(model).link_values(data.qvel))
    assert np.array_equal(snap.base_quat, data.qpos[3:7])
    assert np.array_equal(snap.base_linvel, data.qvel[0:3])
    assert np.array_equal(snap.base_angvel, data.qvel[3:6])
    assert snap.imu_quat == pytest.approx(data.qpos[3:7], abs=0.05)  # IMU sits in the pelvis
    # Standing still: the soles carry the weight and the accelerometer reads +g upward.
    support = snap.left_ft[2] + snap.right_ft[2]
    assert support == pytest.approx(robot.total_mass * G, rel=0.1)
    assert np.linalg.norm(snap.imu_acc) == pytest.approx(G, rel=0.05)


def test_motor_encoders_read_the_motor_dof_without_imperfections(coman) -> None:  # noqa: ANN001
    """coman's pre-spring motor encoders read the motor DoF exactly, apart from the link
    encoders' noise and quantization; the link reading is motor + spring."""
    robot, model, data = coman
    spec = SensorsSpec(joint_position_noise=0.01, joint_position_quantization=0.01)
    snap = SensorModel(robot, model, spec, 0.002, 0).read(model, data)
    link = robot.link_joint_qpos_adr(model)
    motor = data.qpos[link.adr[link.starts]]
    assert np.array_equal(snap.motor_pos, motor)
    assert not np.array_equal(snap.joint_pos, motor)  # the springs are pre-loaded at home


def test_no_base_state_unless_the_spec_provides_it(coman) -> None:  # noqa: ANN001
    robot, model, data = coman
    snap = SensorModel(robot, model, SensorsSpec(base_state=False), 0.002, 0).read(model, data)
    assert snap.base_pos is None and snap.base_quat is None
    with pytest.raises(ValueError, match="base_state"):
        snap.pinocchio_state(robot)
    assert set(snap.as_message()) >= {"joint_pos", "left_ft", "base_pos"}


def test_a_reading_is_a_whole_frozen_snapshot(coman) -> None:  # noqa: ANN001
    """The reader builds snapshots without the dataclass __init__: each must still hold every
    field in field order (the /sensors message's key order), compare equal to one built by
    __init__, and refuse assignment."""
    robot, model, data = coman
    for base_state in (True, False):
        snap = SensorModel(robot, model, SensorsSpec(base_state=base_state), 0.002, 0).read(
            model, data
        )
        assert list(vars(snap)) == [f.name for f in dataclasses.fields(SensorSnapshot)]
        assert snap == SensorSnapshot(**vars(snap))
        with pytest.raises(dataclasses.FrozenInstanceError):
            snap.t = 1.0  # type: ignore[misc]


def test_noise_is_seeded_has_the_given_spread_and_leaves_exact_channels_alone(coman) -> None:  # noqa: ANN001
    robot, model, data = coman
    spec = SensorsSpec(joint_velocity_noise=0.01, ft_force_noise=2.0, imu_acc_noise=0.0)
    exact = SensorModel(robot, model, SensorsSpec(), 0.002, 0).read(model, data)

    def readings(seed: int) -> list:
        sensors = SensorModel(robot, model, spec, 0.002, seed)
        return [sensors.read(model, data) for _ in range(300)]

    a, b, c = readings(1), readings(1), readings(2)
    assert all(np.array_equal(x.joint_vel, y.joint_vel) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0].joint_vel, c[0].joint_vel)
    dv = np.array([r.joint_vel - exact.joint_vel for r in a])
    df = np.array([r.left_ft[:3] - exact.left_ft[:3] for r in a])
    assert dv.std() == pytest.approx(0.01, rel=0.1) and df.std() == pytest.approx(2.0, rel=0.1)
    for r in a[:5]:  # channels without noise stay exact
        assert np.array_equal(r.joint_pos, exact.joint_pos)
        assert np.array_equal(r.imu_acc, exact.imu_acc)
        assert np.array_equal(r.left_ft[3:], exact.left_ft[3:])


#: Each noise field of the spec and the channels it must reach: (field, [(snapshot attribute,
#: slice of it)]). The F/T fields reach both feet's sensors.
NOISE_CHANNELS = [
    ("joint_position_noise", [("joint_pos", slice(None))]),
    ("joint_velocity_noise", [("joint_vel", slice(None))]),
    ("imu_gyro_noise", [("imu_gyro", slice(None))]),
    ("imu_acc_noise", [("imu_acc", slice(None))]),
    ("ft_force_noise", [("left_ft", slice(0, 3)), ("right_ft", slice(0, 3))]),
    ("ft_torque_noise", [("left_ft", slice(3, 6)), ("right_ft", slice(3, 6))]),
]
ALL_CHANNELS = [c for _, channels in NOISE_CHANNELS for c in channels]


@pytest.mark.parametrize("field, channels", NOISE_CHANNELS, ids=[f for f, _ in NOISE_CHANNELS])
def test_each_noise_field_reaches_its_channels_and_only_them(coman, field, channels) -> None:  # noqa: ANN001
    """Every noise field of ``sensors:`` acts: its channels get the given spread, and every
    other channel reads exactly (a field that silently did nothing would fail here)."""
    robot, model, data = coman
    std = 0.05
    sensors = SensorModel(robot, model, SensorsSpec(**{field: std}), 0.002, 3)
    exact = SensorModel(robot, model, SensorsSpec(), 0.002, 3).read(model, data)
    reads = [sensors.read(model, data) for _ in range(400)]
    for attr, part in ALL_CHANNELS:
        err = np.array([getattr(r, attr)[part] - getattr(exact, attr)[part] for r in reads])
        if (attr, part) in channels:
            assert err.std() == pytest.approx(std, rel=0.1), (field, attr)
        else:
            assert not err.any(), (field, attr)


def test_quantization_rounds_encoders_to_the_step(coman) -> None:  # noqa: ANN001
    robot, model, data = coman
    step = 0.001534
    snap = SensorModel(robot, model, SensorsSpec(joint_position_quantization=step), 0.002, 0).read(
        model, data
    )
    exact = SensorModel(robot, model, SensorsSpec(), 0.002, 0).read(model, data)
    assert np.allclose(snap.joint_pos / step, np.round(snap.joint_pos / step))
    assert np.abs(snap.joint_pos - exact.joint_pos).max() <= step / 2 + 1e-12


def test_calibration_offset_is_fixed_per_seed_and_zero_by_default(coman) -> None:  # noqa: ANN001
    """A calibration offset is the same in every reading of a run (systematic, not noise), is
    drawn per seed with the given σ, and σ = 0 reads the links exactly."""
    robot, model, data = coman
    exact = SensorModel(robot, model, SensorsSpec(), 0.002, 0).read(model, data)
    zero = SensorModel(robot, model, SensorsSpec(joint_position_offset=0.0), 0.002, 0)
    assert np.array_equal(zero.read(model, data).joint_pos, exact.joint_pos)
    spec = SensorsSpec(joint_position_offset=0.003)
    sensors = SensorModel(robot, model, spec, 0.002, 0)
    first, later = sensors.read(model, data), sensors.read(model, data)
    offset = first.joint_pos - exact.joint_pos
    assert np.array_equal(later.joint_pos - exact.joint_pos, offset)  # the same every tick
    assert np.all(offset != 0) and np.abs(offset).max() < 5 * 0.003
    again = SensorModel(robot, model, spec, 0.002, 0).read(model, data)
    other = SensorModel(robot, model, spec, 0.002, 1).read(model, data)
    assert np.array_equal(again.joint_pos, first.joint_pos)
    assert not np.array_equal(other.joint_pos, first.joint_pos)


def test_calibration_offset_leaves_the_noise_draws_unchanged(coman) -> None:  # noqa: ANN001
    """The offsets come from their own seed stream: adding them shifts the noisy readings by
    the offsets and nothing else."""
    robot, model, data = coman
    noisy = SensorModel(robot, model, SensorsSpec(joint_position_noise=0.001), 0.002, 3)
    both = SensorModel(
        robot, model, SensorsSpec(joint_position_noise=0.001, joint_position_offset=0.003), 0.002, 3
    )
    only = SensorModel(robot, model, SensorsSpec(joint_position_offset=0.003), 0.002, 3)
    exact = SensorModel(robot, model, SensorsSpec(), 0.002, 3).read(model, data).joint_pos
    offset = only.read(model, data).joint_pos - exact
    for _ in range(3):
        a, b = noisy.read(model, data).joint_pos, both.read(model, data).joint_pos
        assert b == pytest.approx(a + offset, abs=1e-15)


def test_backlash_lags_the_link_by_up_to_half_the_play_and_only_where_set(coman) -> None:  # noqa: ANN001
    """Behind a play b the encoder holds still while the link moves within ±b/2, then follows
    it b/2 behind; joints without play read the link exactly."""
    robot, model, data = coman
    play = 0.02
    spec = SensorsSpec(joint_backlash={"*knee": play})
    sensors = SensorModel(robot, model, spec, 0.002, 0)
    knee = [i for i, n in enumerate(robot.joint_names) if n.endswith("knee")]
    other = [i for i, n in enumerate(robot.joint_names) if not n.endswith("knee")]
    link = robot.link_joint_qpos_adr(model)
    start = sensors.read(model, data).joint_pos.copy()
    assert np.array_equal(start, link.link_values(data.qpos))  # starts centred
    knee_adr = [model.joint(robot.joint_names[i]).qposadr[0] for i in knee]
    saved = data.qpos.copy()
    for delta, expected in ((0.006, 0.0), (0.02, 0.01), (0.015, 0.01), (-0.01, -0.0)):
        data.qpos[:] = saved
        data.qpos[knee_adr] += delta  # the spring DoF: the link moves, the motor does not
        mujoco.mj_forward(model, data)
        snap = sensors.read(model, data)
        assert snap.joint_pos[knee] - start[knee] == pytest.approx(np.full(2, expected), abs=1e-12)
        assert np.array_equal(snap.joint_pos[other], link.link_values(data.qpos)[other])
    data.qpos[:] = saved
    mujoco.mj_forward(model, data)


def test_delay_holds_back_whole_control_periods(coman) -> None:  # noqa: ANN001
    robot, model, data = coman
    sensors = SensorModel(robot, model, SensorsSpec(delay=0.004), 0.002, 0)
    seen = []
    for _ in range(5):
        seen.append(sensors.read(model, data).t)
        mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
    t0 = seen[0]
    assert seen[:3] == [t0, t0, t0]  # two readings held back, then one per tick
    assert seen[3] > t0 and seen[4] > seen[3]


def test_contact_wrenches_carry_the_weight_and_match_mj_contact_force(coman) -> None:  # noqa: ANN001
    """The fast read of the constraint forces equals MuJoCo's own ``mj_contactForce``."""
    robot, model, data = coman
    reader = ContactReader(model)
    pairs = reader.read(data)
    assert set(pairs) == {"left_foot/floor", "right_foot/floor"}
    total = sum(pairs.values())
    assert total[2] == pytest.approx(robot.total_mass * G, rel=0.05)
    # Centre of pressure of each foot lies under that foot.
    for side in ("left", "right"):
        w = pairs[f"{side}_foot/floor"]
        cop_y = w[3] / w[2]
        foot_y = data.xpos[model.body(f"{side}_foot").id][1]
        assert cop_y == pytest.approx(foot_y, abs=0.05)
    slow_reader = ContactReader(model)
    slow_reader._elliptic = False  # force the per-contact mj_contactForce path
    slow = slow_reader.read(data)
    for key, wrench in pairs.items():
        assert np.allclose(slow[key], wrench, rtol=1e-12, atol=1e-9)


MIXED_SCENE = """
<mujoco>
  <option cone="elliptic"/>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <body name="left_foot" pos="0 0 0.03">
      <freejoint/>
      <geom type="box" size="0.1 0.05 0.02" mass="2"/>
      <geom type="sphere" pos="-0.2 0 -0.01" size="0.03" mass="0.1"/>
    </body>
    <body name="right_foot" pos="0.35 0.3 0.08">
      <freejoint/>
      <geom type="box" size="0.1 0.05 0.02" mass="2"/>
    </body>
    <body name="block" pos="0.35 0.3 0.02">
      <geom name="obstacle_step" type="box" size="0.2 0.2 0.02"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_contact_pairs_sum_every_contact_of_the_pair_in_the_world_frame() -> None:
    """The floor before the robot's geoms and the obstacle after them (so the force sign flips
    for one and not the other), and two geoms of one body on the floor: the reader's pair
    wrenches equal a contact-by-contact sum."""
    model = mujoco.MjModel.from_xml_string(MIXED_SCENE)
    data = mujoco.MjData(model)
    for _ in range(300):
        mujoco.mj_step(model, data)
    reader = ContactReader(model)
    pairs = reader.read(data)
    expected: dict[str, np.ndarray] = {}
    local = np.zeros(6)
    for i in range(data.ncon):
        c = data.contact[i]
        names = [model.geom(g).name for g in c.geom]
        mujoco.mj_contactForce(model, data, i, local)
        force = c.frame.reshape(3, 3).T @ local[:3]  # force of geom1 on geom2
        world_first = names[0] in ("floor", "obstacle_step")
        robot = c.geom[1] if world_first else c.geom[0]
        if not world_first:
            force = -force
        key = f"{model.body(model.geom_bodyid[robot]).name}/{names[0 if world_first else 1]}"
        wrench = np.concatenate([force, np.cross(c.pos, force)])
        expected[key] = expected.get(key, 0) + wrench
    assert set(pairs) == set(expected) >= {"left_foot/floor", "right_foot/obstacle_step"}
    for key, wrench in expected.items():
        assert np.allclose(pairs[key], wrench, rtol=1e-12, atol=1e-9), key
    assert reader.read(data).keys() == pairs.keys()  # the cached plan gives the same
