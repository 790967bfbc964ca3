"""The point-contact ground law of COMAN's lab's simulator (walkrepro/sim/contact_law.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from walkrepro.sim import contact_law
from walkrepro.sim.contact_law import GroundContact, PointContactLaw, applied, applied_to, sole_grid

#: The lab's parameters (NicolasVdN/CoManRobotran @ 0207863b: simu_def.h, user_ExtForces.c).
LAB = PointContactLaw(
    stiffness=27818.0,
    velocity_scale=0.3,
    tangential_stiffness=1e4,
    tangential_damping=10.0,
    friction=0.9,
)
#: A COMAN-sized sole on the lab's 1 cm grid: 20 × 10 = 200 points.
POINTS = sole_grid((-0.095, 0.095), (-0.045, 0.045), -0.02, 0.01)
G = 9.81


def block(mass: float, timestep: float = 0.0005, height: float = 0.0201) -> mujoco.MjModel:
    """A free box with the sole's footprint, its own MuJoCo contact off (the law holds it)."""
    xml = f"""<mujoco><option timestep="{timestep}" gravity="0 0 -{G}"/>
    <size nuserdata="{GroundContact.userdata_size({"foot": POINTS})}"/>
    <worldbody><geom type="plane" size="1 1 1" contype="0" conaffinity="0"/>
    <body name="foot" pos="0 0 {height}"><freejoint/>
    <geom type="box" size="0.095 0.045 0.02" mass="{mass}" contype="0" conaffinity="0"/>
    </body></worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def run(model: mujoco.MjModel, seconds: float, pull: float = 0.0) -> mujoco.MjData:
    """Settle ``model`` on the ground under the law for 0.5 s, then step it ``seconds`` more,
    pulled along +x by ``pull`` [N]."""
    data = mujoco.MjData(model)
    steps = int(round(seconds / model.opt.timestep))
    with applied(GroundContact(model, LAB, {"foot": POINTS})):
        for _ in range(int(round(0.5 / model.opt.timestep))):
            mujoco.mj_step(model, data)
        data.xfrc_applied[model.body("foot").id, 0] = pull
        for _ in range(steps):
            mujoco.mj_step(model, data)
    return data


def test_a_resting_body_sinks_by_its_weight_over_the_points_stiffness() -> None:
    """At rest the sole sinks δ = m g / (n k): every point carries its share of the weight."""
    mass = 14.0
    data = run(block(mass), 1.0)
    depth = -(data.qpos[2] - 0.02)
    assert depth == pytest.approx(mass * G / (len(POINTS) * LAB.stiffness), rel=1e-4)
    assert np.abs(data.qvel).max() < 1e-4


def test_the_normal_force_is_the_hunt_crossley_law_during_an_impact() -> None:
    """While a flat sole lands, the ground pushes n k δ (1 − ż / v₀): zero at touchdown, more
    while the sole still moves down."""
    model = block(14.0, height=0.021)  # lands from 1 mm
    data = mujoco.MjData(model)
    seen = 0
    with applied(GroundContact(model, LAB, {"foot": POINTS})):
        for _ in range(400):
            mujoco.mj_step1(model, data)  # positions, velocities, passive forces
            depth = -(data.qpos[2] - 0.02)
            if depth > 0:
                expected = len(POINTS) * LAB.stiffness * depth * max(0.0, 1 - data.qvel[2] / 0.3)
                assert data.qfrc_passive[2] == pytest.approx(expected, rel=1e-9)
                seen += 1
            else:
                assert data.qfrc_passive[2] == 0.0
            mujoco.mj_step2(model, data)
    assert seen > 100


def test_a_pull_below_mu_m_g_holds_the_block_and_above_it_slides() -> None:
    """Below Coulomb's bound the anchors hold (the block creeps by F / (n k_t) only); above
    it the block accelerates at (F − μ m g) / m."""
    mass = 14.0
    settle = run(block(mass), 1.0)
    held = run(block(mass), 1.0, pull=0.5 * LAB.friction * mass * G)
    creep = held.qpos[0] - settle.qpos[0]
    assert (
        0 < creep < 1.5 * 0.5 * LAB.friction * mass * G / (len(POINTS) * LAB.tangential_stiffness)
    )
    pull = 1.5 * LAB.friction * mass * G
    model = block(mass)
    data = mujoco.MjData(model)
    with applied(GroundContact(model, LAB, {"foot": POINTS})):
        for _ in range(1000):  # settle on the ground
            mujoco.mj_step(model, data)
        data.xfrc_applied[model.body("foot").id, 0] = pull
        for _ in range(400):  # start sliding
            mujoco.mj_step(model, data)
        v0, t0 = data.qvel[0], data.time
        for _ in range(1000):
            mujoco.mj_step(model, data)
        acceleration = (data.qvel[0] - v0) / (data.time - t0)
    assert acceleration == pytest.approx((pull - LAB.friction * mass * G) / mass, rel=0.02)


def test_split_steps_and_a_replay_with_mj_step_are_bit_identical() -> None:
    """The runner's mj_step1 + mj_step2 and verify's mj_step give the same states bit for bit,
    and the anchors kept in userdata survive a copy of the data mid-run."""
    model = block(14.0)
    foot = model.body("foot").id
    pull = 1.2 * LAB.friction * 14.0 * G
    runner = mujoco.MjData(model)
    replay = mujoco.MjData(model)
    with applied(GroundContact(model, LAB, {"foot": POINTS})):
        for step in range(1500):
            for data in (runner, replay):
                data.xfrc_applied[foot, 0] = pull if step > 600 else 0.0
            mujoco.mj_step1(model, runner)
            mujoco.mj_step2(model, runner)
            mujoco.mj_step(model, replay)
            assert np.array_equal(runner.qpos, replay.qpos)
            assert np.array_equal(runner.userdata, replay.userdata)
            if step == 800:  # save mid-slide, continue from the copy
                saved = mujoco.MjData(model)
                mujoco.mj_copyData(saved, model, replay)
                replay = saved
    assert runner.userdata[2 : 3 * len(POINTS) : 3].sum() == len(POINTS)  # every point anchored


def test_the_compiled_callback_and_the_python_dispatcher_step_alike() -> None:
    """The law compiled as MuJoCo's C callback (one law applied) and the Python dispatcher
    (two laws at once) give the same states and anchors bit for bit, sliding included."""
    model, other = block(14.0), block(6.4)
    foot = model.body("foot").id
    pull = 1.2 * LAB.friction * 14.0 * G
    native, python = mujoco.MjData(model), mujoco.MjData(model)
    law = GroundContact(model, LAB, {"foot": POINTS})
    for step in range(1500):
        for data in (native, python):
            data.xfrc_applied[foot, 0] = pull if step > 600 else 0.0
        with applied(law):
            assert mujoco.get_mjcb_passive() is not contact_law._passive
            mujoco.mj_step(model, native)
            with applied(GroundContact(other, LAB, {"foot": POINTS})):
                assert mujoco.get_mjcb_passive() is contact_law._passive
                mujoco.mj_step(model, python)
        assert np.array_equal(native.qpos, python.qpos)
        assert np.array_equal(native.userdata, python.userdata)
    assert native.qvel[0] > 0.1  # it slid


def test_the_compiled_callback_leaves_a_model_of_other_sizes_alone() -> None:
    """A model of other sizes stepped while a law is applied (as one compiled meanwhile would
    be) gets no force from it."""
    free = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body pos="0 0 -1"><freejoint/><geom size="0.1"/></body>'
        "</worldbody></mujoco>"
    )
    data = mujoco.MjData(free)
    with applied(GroundContact(block(1.0), LAB, {"foot": POINTS})):
        mujoco.mj_step(free, data)
    assert not data.qfrc_passive.any()


@pytest.mark.parametrize(("mass", "stable_up_to"), [(1.0, 0.0005), (6.4, 0.001), (14.0, 0.001)])
def test_the_explicit_law_is_stable_up_to_a_measured_timestep(
    mass: float, stable_up_to: float
) -> None:
    """Landing from 1 cm (0.44 m/s), the lab's law settles at its own 0.5 ms step on a 1 kg
    sole and at 1 ms under a COMAN leg's 6.4 kg or more; at twice those steps it diverges
    (the forces are explicit, as the lab's are)."""
    for timestep, stable in ((stable_up_to, True), (2 * stable_up_to, False)):
        model = block(mass, timestep, height=0.03)
        data = mujoco.MjData(model)
        with applied(GroundContact(model, LAB, {"foot": POINTS})):
            for _ in range(int(round(1.5 / timestep))):
                mujoco.mj_step(model, data)
        settled = (
            np.isfinite(data.qpos).all()
            and abs(data.qpos[2] - 0.02) < 0.01
            and abs(data.qvel[2]) < 0.05
        )
        assert settled == stable, (mass, timestep, data.qpos[2], data.qvel[2])


def test_models_compile_again_once_the_law_is_no_longer_applied() -> None:
    """MuJoCo's passive callback is set only while a law is applied."""
    run(block(1.0), 0.01)
    assert mujoco.get_mjcb_passive() is None
    block(1.0)  # compiles


def test_a_model_without_room_for_the_anchors_is_refused() -> None:
    """The law's state needs 3 userdata slots per point; fewer is an error that says so."""
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="foot"><freejoint/><geom size="0.1"/></body>'
        "</worldbody></mujoco>"
    )
    with pytest.raises(ValueError, match="606 userdata slots"):
        GroundContact(model, LAB, {"foot": POINTS})


def test_the_law_refuses_non_physical_parameters() -> None:
    """A zero stiffness or friction, or a negative damping, is refused."""
    with pytest.raises(ValueError, match="stiffness"):
        PointContactLaw(0.0, 0.3, 1e4, 10.0, 0.9)
    with pytest.raises(ValueError, match="tangential_damping"):
        PointContactLaw(1.0, 0.3, 1e4, -1.0, 0.9)


def test_a_model_carries_its_law_in_its_mjcf() -> None:
    """mjcf() writes the law and its soles into a model; from_model() reads back the same."""
    from walkrepro.sim.contact_law import from_model, mjcf

    xml = f"""<mujoco>{mjcf(LAB, {"foot": POINTS})}
    <worldbody><body name="foot"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    contact = from_model(model)
    assert contact is not None and contact.law == LAB
    assert np.array_equal(contact.points["foot"], POINTS)
    assert model.nuserdata == 3 * len(POINTS) + 6  # anchors, then the wrench
    assert from_model(mujoco.MjModel.from_xml_string("<mujoco/>")) is None


def test_coman_stands_on_the_lab_law_and_its_log_replays_bit_for_bit(
    tmp_path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A robot whose model carries the law runs under it (MuJoCo's own sole contact
    excluded), and walkrepro verify replays its log with the law to zero deviation."""
    from pathlib import Path

    import walkrepro.sim.robot as robot_module
    from walkrepro.log.record import read_log
    from walkrepro.runs.runner import run
    from walkrepro.sim.contact_law import mjcf
    from walkrepro.sim.replay import verify_log
    from walkrepro.specs.files import load_spec

    # COMAN's sole (0.22 × 0.10 m, 3 cm ahead of the ankle, 6 cm below it) on a 1 cm grid.
    sole = sole_grid((-0.08, 0.14), (-0.05, 0.05), -0.06, 0.01)
    source = Path(robot_module.ROBOTS_DIR) / "coman" / "robot.xml"
    law = mjcf(LAB, {"left_foot": sole, "right_foot": sole})
    exclude = (
        '<contact><exclude body1="world" body2="left_foot"/>'
        '<exclude body1="world" body2="right_foot"/></contact>'
    )
    (tmp_path / "coman_law").mkdir()
    (tmp_path / "coman_law" / "robot.xml").write_text(
        source.read_text().replace("</mujoco>", f"{law}\n{exclude}\n</mujoco>")
    )
    monkeypatch.setattr(robot_module, "ROBOTS_DIR", tmp_path)
    spec = load_spec("stand_coman").spec
    spec = spec.model_copy(
        update={"robot": "coman_law", "sim": spec.sim.model_copy(update={"duration": 1.0})}
    )
    result = run(spec, tmp_path / "log.mcap")
    assert result.outcome == "complete", result.message
    report = verify_log(tmp_path / "log.mcap")
    assert report.ok and report.max_deviation == 0.0 and report.n_states_compared > 100
    log = read_log(tmp_path / "log.mcap")
    assert "walkrepro_ground_law" in log.scene_xml  # the log carries its own law
    # The law's forces are in the logged contact pairs and in the feet's F/T sensors: once
    # settled, the feet carry the robot's weight.
    from walkrepro.evaluation.metrics import LogData
    from walkrepro.sim.sensors import SensorModel

    logged = LogData(log)
    weight = logged.robot_mass * 9.81
    feet = logged.foot_normal_force("left_foot") + logged.foot_normal_force("right_foot")
    assert feet[-1] == pytest.approx(weight, rel=0.01)
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    data = mujoco.MjData(model)
    data.qpos[:] = log.messages("/sim/state")[-1]["qpos"]
    robot = robot_module.load_robot("coman_law")
    sensors = SensorModel(robot, model, spec.sensors, spec.sim.control_period, 0)
    with applied_to(model):
        for _ in range(2000):  # settle again from the logged posture, servos at home
            data.ctrl[:] = robot.home_ctrl if hasattr(robot, "home_ctrl") else data.ctrl
            mujoco.mj_step(model, data)
        mujoco.mj_step1(model, data)
        mujoco.mj_step2(model, data)
    snapshot = sensors.read(model, data)
    feet_mass = sum(model.body_subtreemass[model.body(f).id] for f in ("left_foot", "right_foot"))
    vertical = snapshot.left_ft[2] + snapshot.right_ft[2]
    assert vertical == pytest.approx((logged.robot_mass - feet_mass) * 9.81, rel=0.02)
