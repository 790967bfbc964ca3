"""Tests of Paper II's controller on coman, without physics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from walkrepro.controllers import controller_class
from walkrepro.papers.faraji.controller import TimeProjectionParams
from walkrepro.sim.robot import load_robot
from walkrepro.sim.sensors import SensorSnapshot


def _snapshot(robot, t: float) -> SensorSnapshot:
    weight = robot.total_mass * 9.81 / 2
    ft = np.array([0, 0, weight, 0, 0, 0], dtype=float)
    return SensorSnapshot(
        t=t,
        joint_pos=robot.home_joint_pos.copy(),
        joint_vel=np.zeros(robot.n_joints),
        imu_quat=np.array([1.0, 0, 0, 0]),
        imu_gyro=np.zeros(3),
        imu_acc=np.array([0, 0, 9.81]),
        left_ft=ft,
        right_ft=ft,
    )


def _controller(**params):
    robot = load_robot("coman")
    ctrl = controller_class("timeprojection")()
    ctrl.reset(robot, TimeProjectionParams(**params), 0.002)
    return robot, ctrl


def test_holds_home_before_walking() -> None:
    """Before start_time the command is the home keyframe's motor targets."""
    robot, ctrl = _controller()
    cmd = ctrl.step(0.0, _snapshot(robot, 0.0))
    np.testing.assert_allclose(cmd.ctrl, robot.home_ctrl)


def test_first_walking_tick_is_close_to_home() -> None:
    """The IK posture at the first step matches home within a few centiradians (no jump)."""
    robot, ctrl = _controller(start_time=0.0)
    cmd = ctrl.step(0.0, _snapshot(robot, 0.0))
    assert np.max(np.abs(cmd.ctrl[:12] - robot.home_ctrl[:12])) < 0.05
    assert cmd.events and cmd.events[0]["kind"] == "phase"


def test_no_error_gives_no_footstep_adjustment() -> None:
    """Standing exactly on the in-place gait's nominal relative positions gives no adjustment."""
    robot, ctrl = _controller(start_time=0.0)
    cmd = ctrl.step(0.0, _snapshot(robot, 0.0))
    assert cmd.signals["footstep"] == pytest.approx(0.0, abs=1e-3)


def test_stepping_off_gives_zero_attack_angle() -> None:
    """With stepping off the attack angle stays zero whatever the error."""
    robot, ctrl = _controller(start_time=0.0, stepping=False)
    snap = _snapshot(robot, 0.0)
    q = snap.joint_pos.copy()
    q[[2, 8]] -= 0.2  # both hips flexed: the pelvis sits behind the feet
    snap = SensorSnapshot(**{**snap.__dict__, "joint_pos": q})
    for i in range(20):
        cmd = ctrl.step(0.002 * i, snap)
    assert cmd.signals["attack_angle"] == 0.0
    assert cmd.signals["footstep"] != 0.0


def test_relative_footstep_gain_pushes_the_foot_toward_the_fall() -> None:
    """A pelvis ahead of the stance foot (e₂ > 0) moves the swing foot forward relative to it."""
    _, ctrl = _controller()
    assert ctrl.rel_gains[0, 0, 2] > 0 and ctrl.rel_gains[0, 0, 6] > 0


def test_posture_spring_compensation_matches_home_preload() -> None:
    """Eq. 21 from the model at the home posture reproduces the keyframe's spring pre-load (half weight per leg)."""
    import numpy as np
    import pytest as _pytest

    from walkrepro.papers.faraji.controller import TimeProjectionController
    from walkrepro.sim.robot import load_robot

    robot = load_robot("coman")
    controller = TimeProjectionController()
    controller.reset(robot, controller.Params(spring_compensation="posture"), 0.002)
    half_weight = 0.5 * controller._spring_deflection(robot.home_joint_pos[:12], 0, 0.0)
    preload = (robot.home_ctrl - robot.home_joint_pos)[:6]  # motor minus link at home
    for j in (3, 4):  # knee, ankle pitch: the springs that carry the weight
        assert half_weight[j] == _pytest.approx(preload[j], rel=0.1)
    assert np.all(half_weight[[0, 1, 5]] == 0.0)  # yaw and roll carry no sagittal load


def _walking_snapshots(robot, n: int) -> list[SensorSnapshot]:
    """A tick sequence with a tilted IMU and uneven loads, so every branch of step runs."""
    rng = np.random.default_rng(4)
    out = []
    for i in range(n):
        snap = _snapshot(robot, 0.002 * i)
        q = snap.joint_pos + rng.normal(0.0, 0.01, robot.n_joints)
        ft = snap.left_ft * np.array([1, 1, 1.5 - i / n, 1, 1, 1])
        quat = np.array([1.0, 0.01, -0.02, 0.3]) / np.linalg.norm([1.0, 0.01, -0.02, 0.3])
        out.append(
            SensorSnapshot(**{**snap.__dict__, "joint_pos": q, "left_ft": ft, "imu_quat": quat})
        )
    return out


def test_same_snapshots_give_the_same_commands() -> None:
    """Two fresh controllers fed the same ticks return identical commands and signals."""
    robot = load_robot("coman")
    snaps = _walking_snapshots(robot, 400)
    runs = []
    for _ in range(2):
        ctrl = controller_class("timeprojection")()
        ctrl.reset(robot, TimeProjectionParams(start_time=0.1, speed=0.1), 0.002)
        runs.append([ctrl.step(s.t, s) for s in snaps])
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a.ctrl, b.ctrl)
        assert a.signals == b.signals and a.events == b.events


def test_signals_are_plain_floats_and_lists() -> None:
    """Every logged signal is a float or a list of floats (cheap to log, no numpy scalars)."""
    robot = load_robot("coman")
    ctrl = controller_class("timeprojection")()
    ctrl.reset(robot, TimeProjectionParams(start_time=0.0), 0.002)
    for s in _walking_snapshots(robot, 5):
        signals = ctrl.step(s.t, s).signals
    assert "q_cmd_legs" in signals
    for name, value in signals.items():
        values = value if isinstance(value, list) else [value]
        assert all(type(v) is float for v in values), name


def test_timing_splits_the_tick() -> None:
    """timing() reports the four parts of a tick, each non-negative [s]."""
    robot = load_robot("coman")
    ctrl = controller_class("timeprojection")()
    ctrl.reset(robot, TimeProjectionParams(start_time=0.0), 0.002)
    for s in _walking_snapshots(robot, 5):
        ctrl.step(s.t, s)
    split = ctrl.timing()
    assert set(split) == {"estimation", "feedback", "ik", "output"}
    assert all(v >= 0.0 for v in split.values()) and split["ik"] > 0.0


def _walking_still(ticks: int = 40, **params):
    """Commands of a 0.2 m/s gait (or ``params``) on snapshots that stand still."""
    robot, ctrl = _controller(
        **{"start_time": 0.0, "speed": 0.2, "velocity_ramp_steps": 1, **params}
    )
    for i in range(ticks):
        cmd = ctrl.step(0.002 * i, _snapshot(robot, 0.002 * i))
    return robot, cmd


def test_stance_ankle_push_off_moves_a_slow_pelvis_forward() -> None:
    """A pelvis slower than the gait gets a forward ankle torque, and its motor offset turns
    the stance leg forward over the sole (with the sole on the ground); nothing else moves."""
    robot, with_push_off = _walking_still(ankle_damping=1.0)  # walkrepro's, off by default
    _, without = _walking_still(ankle_damping=0.0)
    assert with_push_off.signals["ankle_torque"] > 1.0  # forward [Nm]
    assert without.signals["ankle_torque"] == 0.0
    stance_ankle = 6 + 4  # the right leg stands while the left swings first
    offset = with_push_off.ctrl[stance_ankle] - without.ctrl[stance_ankle]
    assert abs(offset) > 1e-3
    others = np.delete(np.arange(robot.n_joints), stance_ankle)
    np.testing.assert_array_equal(with_push_off.ctrl[others], without.ctrl[others])
    # With the sole on the ground the ankle turns the leg, not the foot: the pelvis seen from
    # the sole frame must move forward.
    model, data = robot.pin_model, robot.pin_model.createData()
    sole = model.getFrameId("right_sole")

    def pelvis_in_sole(q_links: np.ndarray) -> np.ndarray:
        q = pin.neutral(model)
        q[robot.pin_q_idx] = q_links
        pin.framesForwardKinematics(model, data, q)
        placement = data.oMf[sole]
        return placement.rotation.T @ (data.oMi[1].translation - placement.translation)

    q = robot.home_joint_pos.copy()
    before = pelvis_in_sole(q)
    q[stance_ankle] += offset
    assert pelvis_in_sole(q)[0] > before[0]


def test_the_defaults_are_the_papers_controller() -> None:
    """The parameters' defaults are the paper's: Eq. 24 on the motor encoder, Eq. 21 on the
    knees, full footstep gains and no stance-ankle push-off (a walking gait gets none)."""
    p = TimeProjectionParams()
    assert (p.torso_term, p.spring_compensation, p.footstep_scale, p.ankle_damping) == (
        "motor",
        "knees",
        1.0,
        0.0,
    )
    _, walking = _walking_still()
    assert walking.signals["ankle_torque"] == 0.0


def test_stance_ankle_push_off_never_brakes_and_is_off_in_place() -> None:
    """No push-off in place (v = 0) nor for a pelvis faster than the gait; for a backward
    gait a still pelvis lacks speed backward and gets a backward ankle torque."""
    _, in_place = _walking_still(speed=0.0, ankle_damping=1.0)
    assert in_place.signals["ankle_torque"] == 0.0
    _, backward = _walking_still(speed=-0.2, ankle_damping=1.0)
    assert backward.signals["ankle_torque"] < -1.0
    robot, ctrl = _controller(start_time=0.0, speed=0.2, velocity_ramp_steps=1, ankle_damping=1.0)
    for i in range(40):  # both hips extend: the feet run back under the pelvis at ≈ 1 m/s
        snap = _snapshot(robot, 0.002 * i)
        q = snap.joint_pos.copy()
        q[[2, 8]] += 0.0045 * i
        cmd = ctrl.step(0.002 * i, SensorSnapshot(**{**snap.__dict__, "joint_pos": q}))
    assert cmd.signals["e_raw"][3] > 0.0  # faster than the gait
    assert cmd.signals["ankle_torque"] == 0.0


def test_paper_torso_term_targets_motor_encoder_plus_pitch() -> None:
    """With torso_term 'motor', the stance hip's target mid-stance is the motor encoder plus
    the IMU pitch (Eq. 24: a voltage from the pitch alone), whatever the link encoder reads."""
    robot, ctrl = _controller(start_time=0.0, torso_term="motor")
    snap = _snapshot(robot, 0.0)
    motor = robot.home_joint_pos.copy() + 0.03  # a spring deflection the law must not see
    pitch = 0.05
    quat = np.array([np.cos(pitch / 2), 0.0, np.sin(pitch / 2), 0.0])
    t = 0.2  # phase 0.2 s of the first step: γ_stance = exp(−(0.2/0.08)²) ≈ 0.002
    cmd = ctrl.step(
        t, SensorSnapshot(**{**snap.__dict__, "t": t, "imu_quat": quat, "motor_pos": motor})
    )
    swing_side = cmd.signals["swing_side"]
    stance_hip = 8 if swing_side > 0 else 2  # coman's leg order: left 0-5, right 6-11
    assert cmd.ctrl[stance_hip] == pytest.approx(motor[stance_hip] + pitch, abs=2e-3)


def test_paper_knee_compensation_offsets_only_the_knees() -> None:
    """Eq. 21 as the paper writes it (spring_compensation 'knees'): the loaded knee motor
    targets extend by μ·|F|/(m g) and no other leg joint gets an offset, where the other
    modes also offset the ankle pitch for the weight it carries (the home pre-load)."""
    mu = 0.022
    robot, knees = _controller(start_time=0.0, spring_compensation="knees", knee_deflection=mu)
    _, knees0 = _controller(start_time=0.0, spring_compensation="knees", knee_deflection=0.0)
    _, home = _controller(
        start_time=0.0, spring_compensation="posture", knee_deflection=mu
    )  # home-based offsets elsewhere
    snap = _snapshot(robot, 0.0)  # each foot carries half the weight
    a, b, c = (ctrl.step(0.0, snap).ctrl[:12] for ctrl in (knees, knees0, home))
    diff = a - b
    for knee in (3, 9):
        assert diff[knee] == pytest.approx(-0.5 * mu, rel=1e-6)  # knee > 0 is flexion
    np.testing.assert_allclose(np.delete(diff, [3, 9]), 0.0, atol=1e-12)
    preload = (robot.home_ctrl - robot.home_joint_pos)[:12]  # motor minus link at home
    for ankle in (4, 10):  # half weight: the home pre-load, which 'knees' leaves out
        assert abs(preload[ankle]) > 0.01
        assert c[ankle] - a[ankle] == pytest.approx(preload[ankle], rel=1e-6)
    np.testing.assert_allclose((c - a)[[3, 9]], 0.0, atol=1e-12)


def test_knee_compensation_takes_each_knees_mu() -> None:
    """Eq. 21 with (μ_left, μ_right), as Fig. 7 identifies them: each loaded knee target
    extends by its own μ·|F|/(m g) (left knee index 3, right 9)."""
    mu = (0.02, 0.03)
    robot, pair = _controller(start_time=0.0, spring_compensation="knees", knee_deflection=mu)
    _, zero = _controller(start_time=0.0, spring_compensation="knees", knee_deflection=0.0)
    snap = _snapshot(robot, 0.0)  # each foot carries half the weight
    diff = pair.step(0.0, snap).ctrl[:12] - zero.step(0.0, snap).ctrl[:12]
    assert diff[3] == pytest.approx(-0.5 * mu[0], rel=1e-6)
    assert diff[9] == pytest.approx(-0.5 * mu[1], rel=1e-6)
    np.testing.assert_allclose(np.delete(diff, [3, 9]), 0.0, atol=1e-12)


def test_series_compensation_adds_the_servo_yield() -> None:
    """'posture_series' divides the static torques by the servo in series with the spring,
    so each sagittal offset grows by k_spring / k_series (knee 300 and ankle 125 Nm/rad
    behind 1111 Nm/rad servos: 1.27× and 1.11×); the roll and yaw targets do not change."""
    from walkrepro.papers.faraji.openloop import series_stiffness

    robot, series = _controller(start_time=0.0, spring_compensation="posture_series")
    _, spring = _controller(start_time=0.0, spring_compensation="posture")
    snap = _snapshot(robot, 0.0)
    a, b = (ctrl.step(0.0, snap) for ctrl in (series, spring))
    q_des = np.asarray(b.signals["q_cmd_legs"])
    np.testing.assert_allclose(a.signals["q_cmd_legs"], q_des)
    for j, name in ((3, "l_knee"), (4, "l_ankle_pitch")):
        ratio = robot.spring_stiffness[j] / series_stiffness(robot, name)
        assert ratio > 1.1
        offset_series, offset_spring = a.ctrl[j] - q_des[j], b.ctrl[j] - q_des[j]
        assert abs(offset_spring) > 1e-3
        assert offset_series == pytest.approx(ratio * offset_spring, rel=1e-6)
    np.testing.assert_allclose(a.ctrl[[0, 1, 5]], b.ctrl[[0, 1, 5]], atol=1e-12)


def test_locate_interpolates_the_tables_linearly() -> None:
    """`locate` places a phase time on the tables' grid: a sample gives its own gain, past the end the last."""
    _, ctrl = _controller()
    tp = ctrl.tp
    n = len(tp.phases)
    assert tp.locate(tp.phases[3]) == (3, pytest.approx(0.0))
    i, a = tp.locate(0.5 * (tp.phases[3] + tp.phases[4]))
    assert i == 3 and a == pytest.approx(0.5)
    assert tp.locate(tp.step_time) == (n - 2, 1.0)
    assert tp.locate(-1.0) == (0, 0.0)
