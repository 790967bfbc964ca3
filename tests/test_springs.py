"""Series springs with a dead band (drive backlash): the law, the ledger, a spec's override."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from walkrepro.publish.ledger import robot_ledger
from walkrepro.sim.robot import load_robot, with_scene_springs
from walkrepro.sim.springs import preload_deflection, spring_law
from walkrepro.sim.world import build_scene
from walkrepro.specs.models import ExperimentSpec

K, B = 395.46, 0.04  # spring [Nm/rad], band [rad]

# A link on a motor DoF and a spring DoF (robots/coman_lab's two-hinge drive), the spring a
# dead-band tendon as robots/build_models.py writes it.
DRIVE = f"""<mujoco><option gravity="0 0 0"/>
<worldbody><body>
  <joint name="j_motor" type="hinge" axis="0 1 0" armature="0.23" damping="12"/>
  <joint name="j" type="hinge" axis="0 1 0"/>
  <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02" mass="1"/>
</body></worldbody>
<tendon><fixed name="j_spring" stiffness="{K}" springlength="{-B / 2} {B / 2}">
  <joint joint="j" coef="1"/></fixed></tendon>
<actuator><position name="j" joint="j_motor" kp="1111"/></actuator>
</mujoco>"""


def spring_torques(q_s: float) -> np.ndarray:
    """Passive spring torques (motor DoF, spring DoF) [Nm] at spring angle ``q_s``."""
    model = mujoco.MjModel.from_xml_string(DRIVE)
    data = mujoco.MjData(model)
    data.qpos[:] = (0.3, q_s)
    mujoco.mj_forward(model, data)
    return data.qfrc_spring.copy()


@pytest.mark.parametrize("q_s", [-0.019, -0.01, 0.0, 0.005, 0.0199])
def test_no_torque_inside_the_band(q_s: float) -> None:
    """Inside the dead band |q_s| < b/2 the drive transmits no spring torque."""
    np.testing.assert_array_equal(spring_torques(q_s), [0.0, 0.0])


@pytest.mark.parametrize("q_s", [-0.1, -0.03, 0.021, 0.05])
def test_spring_torque_outside_the_band(q_s: float) -> None:
    """Outside the band the torque is the spring's, K (|q_s| − b/2), on the relative DoF only
    (so equal and opposite on motor and link)."""
    expected = -K * (q_s - np.sign(q_s) * B / 2)
    tau = spring_torques(q_s)
    assert tau[0] == 0.0
    assert tau[1] == pytest.approx(expected, rel=1e-12)


def test_preload_deflection_inverts_the_law() -> None:
    """The home pre-load angle gives back the torque it is solved for, band closed on its side."""
    model = mujoco.MjModel.from_xml_string(DRIVE)
    assert spring_law(model, "j") == pytest.approx((K, B))
    for torque in (-7.0, 2.5):
        q_s = preload_deflection(torque, K, B)
        assert abs(q_s) > B / 2
        assert spring_torques(q_s)[1] == pytest.approx(torque, rel=1e-12)
    assert preload_deflection(0.0, K, B) == 0.0


def test_ledger_lists_the_backlash_with_its_class() -> None:
    """coman_lab's ledger has the knee and ankle pitch backlash with a provenance class."""
    entry = robot_ledger("coman_lab")["backlash"]
    assert entry.klass in ("source", "paper", "assumed", "calibrated")
    assert set(entry.value) == {"knee", "ankle_pitch"}
    model = load_robot("coman_lab").mj_model
    for side in ("l", "r"):
        for kind in ("knee", "ankle_pitch"):
            assert spring_law(model, f"{side}_{kind}")[1] == pytest.approx(entry.value[kind])


def test_spec_springs_reset_the_home_preload() -> None:
    """actuators.spring / .backlash set the scene's springs; the robot's home is re-solved so
    every spring holds the same torque at the same link posture."""
    robot = load_robot("coman_lab")
    spec = ExperimentSpec.model_validate(
        {
            "name": "t",
            "description": "d",
            "paper": {"key": "walkrepro"},
            "robot": "coman_lab",
            "controller": {"type": "posture"},
            "sim": {"duration": 1.0, "timestep": 0.00025, "control_period": 0.002},
            "actuators": {"spring": {"*ankle_pitch": 150.0}, "backlash": {"*knee": 0.06}},
        }
    )
    model = build_scene(robot, spec).model
    assert spring_law(model, "r_ankle_pitch") == pytest.approx((150.0, 0.0))
    assert spring_law(model, "l_knee") == pytest.approx((395.46, 0.06))
    solved = with_scene_springs(robot, model)
    np.testing.assert_allclose(solved.home_joint_pos, robot.home_joint_pos)
    torques = []
    for r, m in ((robot, robot.mj_model), (solved, model)):
        data = mujoco.MjData(m)
        data.qpos[: r.home_qpos.size] = r.home_qpos
        mujoco.mj_forward(m, data)
        adr = r.link_joint_qvel_adr()
        torques.append(data.qfrc_spring[adr.adr[adr.starts + 1]])
        links = r.link_joint_qpos_adr().link_values(data.qpos)
        np.testing.assert_allclose(links, robot.home_joint_pos, atol=1e-12)
    np.testing.assert_allclose(torques[1], torques[0], atol=1e-9)
    # The servos still balance their springs: kp (ctrl − q_m) is unchanged.
    adr = robot.link_joint_qpos_adr()
    motors = adr.adr[adr.starts]
    np.testing.assert_allclose(
        solved.home_ctrl - solved.home_qpos[motors], robot.home_ctrl - robot.home_qpos[motors]
    )
