"""The contact (docs/contact.md): the sourced numbers, what MuJoCo makes of a contact's
parameters, and that every shipped experiment stands on the contact in force unless its spec
says why not."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from walkrepro.errors import SpecError
from walkrepro.sim.contact_model import (
    AREAL_STIFFNESS,
    DEFAULT_CONTACT,
    ContactModel,
    contact_model,
    geyer_damping_ratio,
    sourced_contact,
    sourced_natural_frequency,
    spring_damper,
)
from walkrepro.sim.robot import load_robot
from walkrepro.sim.world import build_scene
from walkrepro.specs.files import experiment_names, load_spec
from walkrepro.specs.models import ContactSpec


@pytest.mark.parametrize(
    ("robot", "omega", "geyer_zeta"),
    [("dyros_red", 373.8, 0.0437), ("coman", 451.7, 0.0362), ("kist_humanoid", 390.2, 0.0419)],
)
def test_sourced_numbers_are_the_documented_ones(
    robot: str, omega: float, geyer_zeta: float
) -> None:
    """ω = √(κ A / m) from the robot's mass and sole, as tabled in docs/contact.md, and the
    source's damping linearised under the robot's weight."""
    r = load_robot(robot)
    assert sourced_natural_frequency(r) == pytest.approx(omega, abs=0.05)
    assert geyer_damping_ratio(omega) == pytest.approx(geyer_zeta, abs=5e-5)
    model = sourced_contact(r)
    assert model.solref == pytest.approx((-(omega**2), -2.0 * omega), rel=2e-4)
    assert model.time_constant == pytest.approx(1.0 / omega, rel=2e-4)
    assert AREAL_STIFFNESS == pytest.approx(2.7818e8)


def _bounce(
    model: ContactModel, mass: float, v0: float = 0.1, dt: float = 2e-5
) -> tuple[float, float]:
    """Drop a box on a floor with ``model``'s contact, gravity off: (contact time [s],
    restitution)."""
    solref = " ".join(f"{x:.10g}" for x in model.solref)
    xml = f"""<mujoco><option timestep="{dt}" gravity="0 0 0" cone="elliptic" solver="Newton"/>
    <worldbody><geom type="plane" size="0 0 1" priority="1" solref="{solref}"/>
    <body pos="0 0 0.01"><freejoint/><geom type="box" size="0.1 0.05 0.01" mass="{mass}"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[2] = -v0
    for step in range(1, 200000):
        mujoco.mj_step(m, d)
        if d.qvel[2] > 0 and d.qpos[2] >= 0.01:
            return step * dt, float(d.qvel[2]) / v0
    raise AssertionError("the box never left the floor")


def test_mujoco_gives_the_model_its_frequency_and_damping_whatever_the_mass() -> None:
    """The direct-form solref is a linear spring-damper per unit mass: a lightly damped bounce
    lasts half a damped period and restitutes exp(-ζπ/√(1-ζ²)), for 1 kg as for 100 kg; a
    stiffer contact is shorter. A wrong conversion (e.g. the stiffness off by the impedance)
    would move the contact time."""
    omega, zeta = 400.0, 0.05
    light = spring_damper(omega, zeta, "test")
    damped = math.sqrt(1.0 - zeta**2)
    for mass in (1.0, 100.0):
        duration, restitution = _bounce(light, mass)
        assert duration == pytest.approx(math.pi / (omega * damped), rel=0.02)
        assert restitution == pytest.approx(math.exp(-zeta * math.pi / damped), abs=0.02)
    stiff_duration, _ = _bounce(spring_damper(2 * omega, zeta, "test"), 1.0)
    assert stiff_duration == pytest.approx(math.pi / (2 * omega * damped), rel=0.02)
    # Critically damped: the body leaves slowly, far below a lightly damped bounce.
    _, critical = _bounce(spring_damper(omega, 1.0, "test"), 10.0)
    assert critical < 0.2


def test_a_contact_faster_than_two_timesteps_is_refused() -> None:
    """MuJoCo's guidance, 1/ω ≥ 2 timesteps: refused with the field to change."""
    robot = load_robot("coman")
    override = ContactSpec(time_constant=0.0009, reason="test")
    with pytest.raises(SpecError, match="2 × sim.timestep"):
        contact_model(robot, override, timestep=0.0005)
    assert contact_model(robot, override, timestep=0.0004).time_constant == pytest.approx(0.0009)
    assert contact_model(robot, None, 0.0005) is DEFAULT_CONTACT
    sourced = ContactSpec(sourced=True, reason="test")
    assert contact_model(robot, sourced, 0.0005).solref == sourced_contact(robot).solref
    with pytest.raises(SpecError, match="2 × sim.timestep"):
        contact_model(robot, sourced, timestep=0.0015)


def test_the_contact_in_force_is_mujocos_default() -> None:
    """Declared, not hidden: the floor of a scene without a departure carries MuJoCo's default
    solref and solimp, exactly."""
    assert DEFAULT_CONTACT.solref == (0.02, 1.0)
    assert DEFAULT_CONTACT.solimp == (0.9, 0.95, 0.001, 0.5, 2.0)
    m = build_scene(load_robot("coman"), load_spec("stand_coman").spec).model
    assert np.array_equal(m.geom_solref[m.geom("floor").id], [0.02, 1.0])
    assert np.array_equal(m.geom_solimp[m.geom("floor").id], [0.9, 0.95, 0.001, 0.5, 2.0])


@pytest.mark.parametrize("name", experiment_names())
def test_every_shipped_experiment_stands_on_the_model_or_says_why(name: str) -> None:
    """The floor and every obstacle carry the contact in force; a departure carries a reason."""
    spec = load_spec(name).spec
    robot = load_robot(spec.robot)
    m = build_scene(robot, spec).model
    world = spec.world
    expected = contact_model(robot, world.contact, spec.sim.timestep)
    if world.contact is None:
        assert expected is DEFAULT_CONTACT
    else:
        assert world.contact.reason.strip()
    assert np.allclose(m.geom_solref[m.geom("floor").id], expected.solref)
    for obstacle in world.obstacles:
        own = m.geom_solref[m.geom(obstacle.name).id]
        if obstacle.solref is None:
            assert np.allclose(own, expected.solref)
        else:
            assert obstacle.solref_reason and obstacle.solref_reason.strip()
            assert np.allclose(own, obstacle.solref)


def _spec_file(tmp_path: Path, world: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(
        "name: s\ndescription: d\npaper: {key: walkrepro}\nrobot: coman\n"
        "controller: {type: posture}\nsim: {duration: 0.1}\n" + world
    )
    return path


@pytest.mark.parametrize(
    ("world", "needle"),
    [
        (
            "world:\n  obstacles:\n    - {name: obstacle_b, size: [0.1, 0.1, 0.1], position: [1, 0, 0.05],"
            " solref: [0.005, 1]}\n",
            "solref_reason",
        ),
        ("world:\n  contact: {time_constant: 0.005}\n", "world.contact.reason"),
        ("world:\n  contact: {time_constant: 0.5, reason: soft}\n", "world.contact.time_constant"),
        ("world:\n  contact: {time_constant: 0.005, sourced: true, reason: r}\n", "not both"),
        ("world:\n  contact: {reason: r}\n", "either time_constant"),
        ("world:\n  contact: {time_constant: 0.0009, reason: r}\n", "2 × sim.timestep"),
    ],
)
def test_a_departure_without_its_reason_is_a_clear_error(
    tmp_path: Path, world: str, needle: str
) -> None:
    """No reason, no departure: the error names the file and the field."""
    path = _spec_file(tmp_path, world)
    with pytest.raises(SpecError, match=needle) as info:
        load_spec(str(path))
    assert "s.yaml" in str(info.value)
