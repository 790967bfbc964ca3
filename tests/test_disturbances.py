"""Disturbance schedule: windows, profiles, frames, events."""

from __future__ import annotations

import numpy as np

from walkrepro.disturbances import DisturbanceSchedule, profile_scale
from walkrepro.spec import DisturbanceSpec


def test_window_and_ramp_profile() -> None:
    """A disturbance acts only inside [start, start + duration); a ramp rises and falls."""
    const = DisturbanceSpec(name="c", body="pelvis", force=(1, 0, 0), start=1.0, duration=2.0)
    assert profile_scale(const, 0.99) == 0 and profile_scale(const, 1.0) == 1
    assert profile_scale(const, 2.99) == 1 and profile_scale(const, 3.0) == 0
    ramp = const.model_copy(update={"profile": "ramp", "ramp_time": 0.5})
    assert np.isclose(profile_scale(ramp, 1.25), 0.5)
    assert np.isclose(profile_scale(ramp, 2.0), 1.0)
    assert np.isclose(profile_scale(ramp, 2.75), 0.5)


def test_controller_frame_is_frozen_at_onset() -> None:
    """A force in a controller frame is rotated by that frame as it was at onset."""
    spec = DisturbanceSpec(
        name="push", body="pelvis", frame="O_w", force=(75, 0, 0), start=0.0, duration=1.0
    )
    schedule = DisturbanceSchedule([spec])
    rot90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    wrenches, events = schedule.wrenches(0.0, lambda name: rot90)
    assert np.allclose(wrenches["pelvis"], [0, 75, 0, 0, 0, 0])
    assert events[0]["kind"] == "disturbance_on"
    wrenches, _ = schedule.wrenches(0.5, lambda name: np.eye(3))  # frame moved: ignored
    assert np.allclose(wrenches["pelvis"], [0, 75, 0, 0, 0, 0])
    wrenches, events = schedule.wrenches(1.0, lambda name: np.eye(3))
    assert wrenches == {} and events[0]["kind"] == "disturbance_off"


def test_wrenches_on_one_body_add_up() -> None:
    """Two disturbances on the same body sum; zero wrenches are not listed."""
    a = DisturbanceSpec(name="a", body="pelvis", force=(1, 2, 3), start=0.0, duration=1.0)
    b = DisturbanceSpec(name="b", body="pelvis", torque=(0, 0, 1), start=0.0, duration=1.0)
    z = DisturbanceSpec(name="z", body="left_foot", start=0.0, duration=1.0)
    wrenches, _ = DisturbanceSchedule([a, b, z]).wrenches(0.5, lambda n: None)
    assert set(wrenches) == {"pelvis"}
    assert np.allclose(wrenches["pelvis"], [1, 2, 3, 0, 0, 1])


def test_hold_is_a_one_sided_capped_spring_damper() -> None:
    """A hold pushes back toward the onset position along its direction, never pulls, and is capped."""
    spec = DisturbanceSpec(
        name="hand", body="pelvis", force=(-1, 0, 0), start=0.0, duration=1.0,
        profile="hold", stiffness=3000.0, damping=300.0, max_force=150.0,
    )  # fmt: skip
    schedule = DisturbanceSchedule([spec])
    state = {"pos": np.zeros(3), "vel": np.zeros(3)}
    lookup = lambda body: (state["pos"], state["vel"])  # noqa: E731
    wrenches, _ = schedule.wrenches(0.0, lambda n: None, lookup)  # grabs at the origin
    assert wrenches == {}  # no displacement, no force
    state["pos"] = np.array([0.02, 0.0, 0.0])  # pushed 2 cm against the hand
    wrenches, _ = schedule.wrenches(0.1, lambda n: None, lookup)
    assert np.allclose(wrenches["pelvis"], [-60.0, 0, 0, 0, 0, 0])
    state["vel"] = np.array([0.1, 0.0, 0.0])  # still moving into the hand: damping adds
    assert np.allclose(
        schedule.wrenches(0.2, lambda n: None, lookup)[0]["pelvis"][:3], [-90.0, 0, 0]
    )
    state["pos"], state["vel"] = np.array([-0.02, 0.0, 0.0]), np.zeros(3)  # moved away: no pull
    assert schedule.wrenches(0.3, lambda n: None, lookup)[0] == {}
    state["pos"] = np.array([0.5, 0.0, 0.0])  # far into the hand: capped
    assert np.allclose(
        schedule.wrenches(0.4, lambda n: None, lookup)[0]["pelvis"][:3], [-150.0, 0, 0]
    )
