"""Step-to-step error map and the landing-constrained DLQR (Paper II, Eqs. 11-14, 17)."""

from __future__ import annotations

import numpy as np
import pytest

from walkrepro.papers.faraji.dlqr import (
    Dlqr,
    constraint_selector,
    default_weights,
    error_map,
)
from walkrepro.papers.faraji.gait import PeriodicGait
from walkrepro.papers.faraji.threelp import (
    Q,
    ThreeLP,
    ThreeLPParams,
    U,
    mirror,
    reconstruction,
    relabel,
    relative_coordinates,
)

# COMAN-like parameters of note 3lp.md §8.
COMAN_LIKE = ThreeLPParams(m1=14.2, m2=6.4, h1=0.524, h2=0.232, h3=0.190, pw=0.064)
T = 0.4


@pytest.fixture(scope="module")
def model() -> ThreeLP:
    return ThreeLP(COMAN_LIKE)


@pytest.fixture(scope="module")
def dlqr(model: ThreeLP) -> Dlqr:
    return Dlqr.solve(model, T)


def next_error(model: ThreeLP, gait: PeriodicGait, error: np.ndarray, du: np.ndarray) -> np.ndarray:
    """E[k+1] of Eq. (12) by propagating the full perturbed state of a given gait."""
    xi = gait.initial().copy()
    xi[Q] += reconstruction() @ error
    xi[U][:4] += du
    end = model.propagator(0.0, T) @ xi
    nominal_end = model.propagator(0.0, T) @ gait.initial()
    to_next = mirror(8) @ relative_coordinates() @ relabel()[Q, Q]
    return to_next @ (end[Q] - nominal_end[Q])


def test_error_map_is_exact_and_speed_independent(model: ThreeLP, dlqr: Dlqr) -> None:
    """Â E + B̂ ΔU is the exact error one step later, around a slow and a fast gait alike."""
    rng = np.random.default_rng(0)
    error = rng.normal(size=8) * 0.02
    du = rng.normal(size=4)
    expected = dlqr.A_hat @ error + dlqr.B_hat @ du
    for speed in (0.0, 0.5):
        gait = PeriodicGait.solve(model, speed, T, 0.25)
        assert np.abs(next_error(model, gait, error, du) - expected).max() < 1e-12


def test_closed_loop_is_stable(dlqr: Dlqr) -> None:
    """The reduced closed loop's eigen moduli lie well inside the unit circle (≈ 0.01-0.3)."""
    moduli = np.abs(dlqr.closed_loop_eigenvalues)
    assert moduli.max() < 0.3 and moduli.min() > 0.005


def test_open_loop_is_unstable(dlqr: Dlqr) -> None:
    """Without feedback (landing velocity reset to zero) the error grows ≈ 3.7× per step."""
    a = dlqr.A_hat.copy()
    a[4:6] = 0.0  # the landing foot becomes the stance foot: its velocity is lost
    assert np.abs(np.linalg.eigvals(a)).max() == pytest.approx(3.76, abs=0.05)


def test_dlqr_correction_lands_the_foot_at_rest(dlqr: Dlqr) -> None:
    """With ΔU = −K E the swing foot lands with zero velocity (Ĉ E[k+1] = 0)."""
    error = np.random.default_rng(1).normal(size=8) * 0.02
    error[4:6] = 0.0  # the swing foot starts at rest
    nxt = dlqr.A_hat @ error + dlqr.B_hat @ dlqr.correction(error)
    assert np.abs(nxt[4:6]).max() < 1e-12


def test_reduced_system_matches_full_closed_loop(dlqr: Dlqr) -> None:
    """On the constraint surface, Â − B̂ K_full equals the reduced Ā − B̄ K."""
    s_y = constraint_selector()
    full = s_y @ (dlqr.A_hat - dlqr.B_hat @ dlqr.gain) @ s_y.T
    assert np.allclose(full[:6, :6], dlqr.A_bar - dlqr.B_bar @ dlqr.K, atol=1e-12)
    assert np.allclose(full[6:, :6], 0.0, atol=1e-10)


def test_riccati_solution(dlqr: Dlqr, model: ThreeLP) -> None:
    """P solves the discrete Riccati equation of the reduced problem."""
    a, b, p, k = dlqr.A_bar, dlqr.B_bar, dlqr.P, dlqr.K
    q, r = default_weights(model)
    s_y = constraint_selector()
    q_bar = (s_y @ q @ s_y.T)[:6, :6]  # R_ww = 0: no G term
    r_bar = r[:2, :2]
    residual = a.T @ p @ a - p - a.T @ p @ b @ k + q_bar
    assert np.abs(residual).max() < 1e-9 * np.abs(p).max()
    assert np.allclose(k, np.linalg.solve(r_bar + b.T @ p @ b, b.T @ p @ a))


def test_gains_are_the_same_in_both_planes(dlqr: Dlqr) -> None:
    """Sagittal and lateral gains coincide, so one gain serves left and right steps."""
    assert np.allclose(dlqr.gain[0::2, 0::2], dlqr.gain[1::2, 1::2])
    assert np.abs(dlqr.gain[0::2, 1::2]).max() == 0.0
    assert np.allclose(mirror(4) @ dlqr.gain @ mirror(8), dlqr.gain)


def test_error_map_at_phase_zero_is_the_step_map(model: ThreeLP, dlqr: Dlqr) -> None:
    """The remaining-step map from t = 0 is Â, B̂ of the DLQR."""
    a, b = error_map(model, 0.0, T)
    assert np.array_equal(a, dlqr.A_hat) and np.array_equal(b, dlqr.B_hat)
