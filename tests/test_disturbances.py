"""Disturbance schedule: windows, profiles, frames, events."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

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


def test_ramped_push_in_a_frozen_frame_is_a_function_of_time_only() -> None:
    """A ramp in O_w rises, holds its peak and falls in the frame frozen at onset, whatever the
    frame does later: the same times give the same wrench (a human's push, not a fixture)."""
    spec = DisturbanceSpec(
        name="hand", body="pelvis", frame="O_w", force=(-75, 0, 0), start=1.0, duration=2.3,
        profile="ramp", ramp_time=0.3,
    )  # fmt: skip
    rot90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    times = (1.15, 1.3, 2.0, 3.0, 3.15, 3.3)
    expect = (37.5, 75.0, 75.0, 75.0, 37.5, 0.0)
    for later in (rot90, np.eye(3)):  # O_w after onset: unchanged, or turned back by 90°
        schedule = DisturbanceSchedule([spec])
        assert schedule.wrenches(1.0, lambda n: rot90)[0] == {}  # the ramp starts from 0
        for k, (t, f) in enumerate(zip(times, expect, strict=True)):
            # onset (first non-zero force) with O_w's x along the world's y, then `later`
            frame = rot90 if k == 0 else later
            wrenches, _ = schedule.wrenches(t, lambda n, frame=frame: frame)
            got = wrenches.get("pelvis", np.zeros(6))
            assert np.allclose(got, [0, -f, 0, 0, 0, 0]), (t, got)


def test_spec_rejects_a_ramp_longer_than_its_window_and_unknown_profiles() -> None:
    """Ramps must fit twice in the window; 'hold' (a state-dependent hand) is not a profile."""
    with pytest.raises(ValidationError):
        DisturbanceSpec(
            name="r", body="pelvis", start=0, duration=0.5, profile="ramp", ramp_time=0.3
        )
    with pytest.raises(ValidationError):
        DisturbanceSpec(name="h", body="pelvis", start=0, duration=1.0, profile="hold")
