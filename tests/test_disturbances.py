"""Disturbance schedule: windows, profiles, frames, events."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from walkrepro.sim.disturbances import DisturbanceSchedule, profile_scale
from walkrepro.specs.models import DisturbanceSpec


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


# ---- the human's hand that holds (kind: hold, Lee et al. §VI-C) ----------------------------


def _hold(**update: object) -> DisturbanceSpec:
    fields: dict[str, object] = dict(
        name="hand", body="pelvis", kind="hold", frame="O_w", axes=["x"], stiffness=2000.0,
        damping=500.0, max_force=200.0, start=1.0, duration=2.0, profile="ramp", ramp_time=0.5,
    )  # fmt: skip
    fields.update(update)
    return DisturbanceSpec(**fields)


class _Body:
    """A body whose CoM position and velocity the test sets (world frame)."""

    def __init__(self) -> None:
        self.pos = np.array([0.1, 0.2, 0.9])
        self.vel = np.zeros(3)

    def __call__(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        return self.pos.copy(), self.vel.copy()


def test_hold_grabs_where_the_body_is_and_pulls_it_back() -> None:
    """At the grab the hand holds the body where it is (no force while it stays); moved 2 cm
    along x of the frame, the engaged hand pulls back with k · 0.02 = 40 N."""
    body = _Body()
    schedule = DisturbanceSchedule([_hold()])
    wrenches, events = schedule.wrenches(1.001, lambda n: np.eye(3), body)  # the grab
    assert events[0]["kind"] == "disturbance_on" and wrenches == {}
    body.pos = body.pos + [0.02, 0.0, 0.0]
    wrenches, _ = schedule.wrenches(2.0, lambda n: np.eye(3), body)
    assert np.allclose(wrenches["pelvis"], [-40.0, 0, 0, 0, 0, 0])


def test_hold_engages_and_releases_over_its_ramps() -> None:
    """The same displacement gives half the force mid-ramp, the full force held, half again
    mid-release, and nothing once the hand has let go."""
    body = _Body()
    schedule = DisturbanceSchedule([_hold()])
    schedule.wrenches(1.001, lambda n: np.eye(3), body)  # the grab
    body.pos = body.pos + [0.02, 0.0, 0.0]
    forces = []
    for t in (1.25, 2.0, 2.75):
        w, _ = schedule.wrenches(t, lambda n: np.eye(3), body)
        forces.append(w["pelvis"][0])
    assert np.allclose(forces, [-20.0, -40.0, -20.0])
    w, events = schedule.wrenches(3.0, lambda n: np.eye(3), body)
    assert w == {} and events[0]["kind"] == "disturbance_off"


def test_hold_acts_only_on_its_axes_in_its_frozen_frame() -> None:
    """A hand holding x of a frame turned 90° about z resists motion along world y only, with
    damping on the velocity; motion along the frame's free axes gets no force."""
    rot90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    body = _Body()
    schedule = DisturbanceSchedule([_hold()])
    schedule.wrenches(1.001, lambda n: rot90, body)
    body.pos = body.pos + [0.05, 0.0, 0.3]  # world x and z: the frame's −y and z, not held
    w, _ = schedule.wrenches(2.0, lambda n: np.eye(3), body)
    assert w == {}
    body.vel = np.array([0.0, 0.1, 0.0])  # world y: the frame's x
    w, _ = schedule.wrenches(2.0, lambda n: np.eye(3), body)
    assert np.allclose(w["pelvis"][:3], [0.0, -50.0, 0.0])


def test_hold_force_is_capped_in_norm() -> None:
    """A hand cannot exceed its cap: 0.5 m away along x and y, |f| = 200 N, in the spring's
    direction."""
    body = _Body()
    schedule = DisturbanceSchedule([_hold(axes=["x", "y"])])
    schedule.wrenches(1.001, lambda n: np.eye(3), body)
    body.pos = body.pos + [0.5, 0.5, 0.0]
    w, _ = schedule.wrenches(2.0, lambda n: np.eye(3), body)
    f = w["pelvis"][:3]
    assert np.linalg.norm(f) == pytest.approx(200.0)
    assert np.allclose(f / np.linalg.norm(f), [-(0.5**0.5), -(0.5**0.5), 0.0])


def test_hold_needs_the_body_state() -> None:
    """A hold without the body's state cannot grab: a clear error, not a silent zero."""
    with pytest.raises(RuntimeError, match="needs the body's state"):
        DisturbanceSchedule([_hold()]).wrenches(1.001, lambda n: np.eye(3))


@pytest.mark.parametrize(
    "update, message",
    [
        ({"force": (10.0, 0.0, 0.0)}, "outcome of its stiffness"),
        ({"stiffness": 0.0}, "stiffness > 0"),
        ({"max_force": 0.0}, "max_force > 0"),
        ({"axes": []}, "at least one axis"),
        ({"axes": ["x", "x"]}, "must not repeat"),
        ({"profile": "constant", "ramp_time": 0.0}, "needs profile: ramp"),
    ],
)
def test_spec_rejects_a_hold_without_a_hand(update: dict, message: str) -> None:
    """A hold must be a hand: stiffness, a cap, axes, a ramp, and no set force."""
    with pytest.raises(ValidationError, match=message):
        _hold(**update)


def test_spec_rejects_hold_fields_on_a_push() -> None:
    """Stiffness on a push would be silently ignored: it is refused."""
    with pytest.raises(ValidationError, match="belong to a hold"):
        DisturbanceSpec(name="p", body="pelvis", force=(1, 0, 0), stiffness=100.0, start=0,
                        duration=1)  # fmt: skip


def test_hold_offset_moves_where_the_hand_holds_in_its_frozen_frame() -> None:
    """With hold_offset the anchor is the grab's centre of mass plus the offset along the
    frame (frozen at the grab): a body that stays put is pulled toward it with k · offset, a
    body that moved onto it feels nothing, and the grab event logs the anchor."""
    rot90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    body = _Body()
    grabbed = body.pos.copy()
    schedule = DisturbanceSchedule([_hold(hold_offset=(-0.01, 0.0, 0.0))])
    _, events = schedule.wrenches(1.001, lambda n: rot90, body)  # frame x = world y
    assert np.allclose(events[0]["anchor"], grabbed + [0.0, -0.01, 0.0])
    w, _ = schedule.wrenches(2.0, lambda n: np.eye(3), body)  # frame moved: ignored
    assert np.allclose(w["pelvis"], [0.0, -20.0, 0.0, 0, 0, 0])  # 2 kN/m · 1 cm toward −y
    body.pos = grabbed + [0.0, -0.01, 0.0]
    w, _ = schedule.wrenches(2.0, lambda n: np.eye(3), body)
    assert w == {}


def test_hold_without_offset_holds_where_it_grabbed() -> None:
    """The default offset is zero: the anchor is the centre of mass at the grab, exactly."""
    body = _Body()
    _, events = DisturbanceSchedule([_hold()]).wrenches(1.001, lambda n: np.eye(3), body)
    assert events[0]["anchor"] == body.pos.tolist()


@pytest.mark.parametrize(
    "update, message",
    [
        ({"hold_offset": (0.0, 0.01, 0.0)}, "does not hold"),
        ({"hold_offset": (0.6, 0.0, 0.0)}, "norm must be <= 0.5"),
    ],
)
def test_spec_rejects_an_offset_the_hand_cannot_hold(update: dict, message: str) -> None:
    """An offset along an axis the hand leaves free would do nothing, and one beyond an arm's
    reach is no hand: both are refused with the reason."""
    with pytest.raises(ValidationError, match=message):
        _hold(**update)


def test_spec_rejects_a_hold_offset_on_a_push() -> None:
    """A push has no anchor: a hold_offset on it is refused."""
    with pytest.raises(ValidationError, match="belong to a hold"):
        DisturbanceSpec(name="p", body="pelvis", force=(1, 0, 0), hold_offset=(0.01, 0, 0),
                        start=0, duration=1)  # fmt: skip
