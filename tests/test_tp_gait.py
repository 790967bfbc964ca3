"""Periodic 3LP gait (Paper II, Eqs. 9-10)."""

from __future__ import annotations

import numpy as np
import pytest

from walkrepro.papers.faraji.gait import PeriodicGait
from walkrepro.papers.faraji.threelp import (
    N_XI,
    Q,
    ThreeLP,
    ThreeLPParams,
    mirror,
    relative_coordinates,
)

# COMAN-like parameters of note 3lp.md §8; step width 25 cm from Paper II.
COMAN_LIKE = ThreeLPParams(m1=14.2, m2=6.4, h1=0.524, h2=0.232, h3=0.190, pw=0.064)
T, V, W = 0.4, 0.3, 0.25


@pytest.fixture(scope="module")
def model() -> ThreeLP:
    return ThreeLP(COMAN_LIKE)


@pytest.fixture(scope="module")
def gait(model: ThreeLP) -> PeriodicGait:
    return PeriodicGait.solve(model, V, T, W)


def touchdown(xi: np.ndarray) -> np.ndarray:
    """Physical touchdown: swap the feet, both at rest; pelvis velocity kept."""
    q = xi[Q].copy()
    q[0:2], q[4:6] = q[4:6].copy(), q[0:2].copy()
    q[6:8] = q[10:12] = 0.0
    return q


def test_gait_is_a_fixed_point_of_the_phase_map(model: ThreeLP, gait: PeriodicGait) -> None:
    """One step plus touchdown returns the mirrored start in relative coordinates."""
    assert gait.residual < 1e-12
    end = model.propagator(0.0, T) @ gait.initial(+1)
    m = relative_coordinates()
    assert np.abs(m @ touchdown(end) - m @ gait.initial(-1)[Q]).max() < 1e-12


def test_swing_foot_lands_at_rest_on_the_next_footstep(gait: PeriodicGait) -> None:
    """The swing foot lands with zero velocity at (v T, W), the pelvis advances v T."""
    q_end = gait.state(T)
    assert np.abs(q_end[6:8]).max() < 1e-12
    assert np.allclose(q_end[0:2], (V * T, W), atol=1e-12)
    assert q_end[2] - gait.state(0.0)[2] == pytest.approx(V * T, abs=1e-12)


def test_sagittal_hip_torque_is_antisymmetric(gait: PeriodicGait) -> None:
    """The sagittal hip torque runs from −τ to +τ over the step, τ_r = −2 τ_c / T.

    With the note's point-mass parameters τ = 1.84 Nm (the note quotes ≈ 6.4 Nm, which these
    equations give only with leg inertias I2 = I3 ≈ 0.2 kg m²).
    """
    u = gait.inputs()
    assert u[2] == pytest.approx(-2 * u[0] / T, rel=1e-9)
    assert gait.hip_torque(0.0)[0] == pytest.approx(-1.838, abs=1e-3)
    assert gait.hip_torque(T)[0] == pytest.approx(-gait.hip_torque(0.0)[0], rel=1e-9)


def test_gait_is_linear_in_speed(model: ThreeLP) -> None:
    """The sagittal gait scales with speed; walking in place needs no sagittal torque."""
    g0 = PeriodicGait.solve(model, 0.0, T, W)
    g1 = PeriodicGait.solve(model, 0.15, T, W)
    g2 = PeriodicGait.solve(model, 0.3, T, W)
    assert np.allclose(g2.start - g0.start, 2 * (g1.start - g0.start), atol=1e-12)
    assert np.abs(g0.start[0::2]).max() < 1e-12  # every x entry of ξ vanishes in place


def test_nominal_state_matches_closed_form(model: ThreeLP, gait: PeriodicGait) -> None:
    """q̄(t) (modal evaluation, Eq. 10) equals Φ(0, t) ξ̄; side −1 is its mirror image."""
    for t in (0.0, 0.1, 0.27, T):
        expected = (model.propagator(0.0, t) @ gait.start)[Q]
        assert np.abs(gait.state(t) - expected).max() < 1e-12
        assert np.allclose(gait.state(t, side=-1), mirror(12) @ gait.state(t))
    assert np.allclose(gait.initial(-1), mirror(N_XI) @ gait.initial(+1))


def test_lateral_bounce_is_centred(gait: PeriodicGait) -> None:
    """The pelvis starts half-way between the feet and bounces back toward the stance side."""
    q0 = gait.state(0.0)
    assert q0[3] == pytest.approx(W / 2, abs=1e-12)
    assert q0[9] < 0.0  # moving toward the stance foot at y = 0


def test_ankle_torque_profile_is_respected(model: ThreeLP) -> None:
    """A prescribed ankle-torque profile is kept, and the gait stays periodic."""
    ankle = np.array([0.5, 0.0, -2.5, 0.0])
    g = PeriodicGait.solve(model, V, T, W, ankle_torque=ankle)
    assert np.allclose(g.inputs()[4:8], ankle) and g.residual < 1e-12


def test_sagittal_relative_state_matches_the_full_one(gait: PeriodicGait) -> None:
    """The per-tick float path gives the sagittal entries of M q̄(t) on both sides."""
    for t in np.linspace(0.0, T, 17):
        for side in (1, -1):
            full = gait.relative_state(t, side)[[0, 2, 4, 6]]
            np.testing.assert_allclose(gait.sagittal_relative_state(t), full, atol=1e-12)
