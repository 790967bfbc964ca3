"""3LP model: equations of motion, closed-form propagation, step-to-step coordinates."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from walkrepro.papers.faraji.threelp import (
    N_XI,
    D,
    Q,
    ThreeLP,
    ThreeLPParams,
    mirror,
    reconstruction,
    relabel,
    relative_coordinates,
)

# COMAN-like parameters of note 3lp.md §8 (a test fixture, not a library default).
COMAN_LIKE = ThreeLPParams(m1=14.2, m2=6.4, h1=0.524, h2=0.232, h3=0.190, pw=0.064)


@pytest.fixture(scope="module")
def model() -> ThreeLP:
    return ThreeLP(COMAN_LIKE)


def random_xi(seed: int) -> np.ndarray:
    """A random ξ with realistic scales: positions, velocities, torques, disturbances."""
    scale = np.r_[np.full(6, 0.1), np.full(6, 1.0), np.full(8, 10.0), 10.0, 10.0, 0.05, 0.05]
    return np.random.default_rng(seed).normal(size=N_XI) * scale


def test_closed_form_matches_numerical_integration(model: ThreeLP) -> None:
    """Φ(t0, Δ) agrees with solve_ivp on ξ̇ = (F0 + t F1) ξ to better than 1e-9."""
    xi = random_xi(0)
    t0, dt = 0.1, 0.3
    sol = solve_ivp(
        lambda t, x: (model.F0 + t * model.F1) @ x,
        (t0, t0 + dt),
        xi,
        method="DOP853",
        rtol=1e-13,
        atol=1e-14,
    )
    closed = model.propagator(t0, dt) @ xi
    assert np.abs(sol.y[:, -1] - closed).max() < 1e-9 * np.abs(closed).max()


def test_propagator_composes(model: ThreeLP) -> None:
    """Φ(a, b) Φ(0, a) = Φ(0, a + b): the ramp clock carries over between pieces."""
    a, b = 0.13, 0.21
    composed = model.propagator(a, b) @ model.propagator(0.0, a)
    assert np.abs(composed - model.propagator(0.0, a + b)).max() < 1e-12


def test_closed_form_split(model: ThreeLP) -> None:
    """A(t), B(t), C(t) of Eq. (5) reproduce the propagated state."""
    xi = random_xi(1)
    cf = model.closed_form(0.25, t0=0.05)
    q = cf.A @ xi[Q] + cf.B @ xi[12:20] + cf.C @ xi[D]
    assert np.allclose(q, (model.propagator(0.05, 0.25) @ xi)[Q], atol=1e-13)


def test_modal_form_matches_matrix_exponential(model: ThreeLP) -> None:
    """The cosh/sinh/cos/sin modal closed form equals the expm closed form."""
    xi = random_xi(2)
    coef = model.modal_coefficients(xi)
    for t in (0.0, 0.07, 0.2, 0.4):
        expected = (model.propagator(0.0, t) @ xi)[Q]
        assert np.abs(coef @ model.modal_basis(t) - expected).max() < 1e-12


def test_translation_invariance(model: ThreeLP) -> None:
    """Columns acting on x sum to zero, so shifting every point changes no acceleration."""
    assert np.abs(model.axis.Cx.sum(axis=1)).max() < 1e-12
    shift = np.zeros(12)
    shift[0:6] = np.tile([0.3, -0.2], 3)  # every point moved by (0.3, -0.2)
    a = model.closed_form(0.4).A
    assert np.allclose(a @ shift, shift, atol=1e-12)


def test_axes_are_decoupled_and_stance_foot_is_still(model: ThreeLP) -> None:
    """x and y never mix, and the stance foot does not accelerate."""
    phi = model.propagator(0.0, 0.4)
    assert np.abs(phi[0::2, 1::2]).max() == 0 and np.abs(phi[1::2, 0::2]).max() == 0
    assert np.abs(model.axis.Cx[2]).max() == 0 and np.abs(model.axis.Cu[2]).max() == 0


def test_frequencies_of_coman_like_parameters(model: ThreeLP) -> None:
    """ω_fall ≈ 4.2 rad/s and ω_swing ≈ 7.2 rad/s with point masses (note §8)."""
    assert model.omega_fall == pytest.approx(4.18, abs=0.02)
    assert model.omega_swing == pytest.approx(7.16, abs=0.02)


def test_pendulum_limits() -> None:
    """A very heavy torso gives the LIP ω² = g/z_t and the hanging-leg pendulum ω² = g/h2."""
    p = ThreeLPParams(m1=1e7, m2=6.4, h1=0.524, h2=0.232, h3=0.190, pw=0.064)
    model = ThreeLP(p)
    assert model.omega_fall**2 == pytest.approx(p.g / (p.h1 + p.h3), rel=1e-5)
    assert model.omega_swing**2 == pytest.approx(p.g / p.h2, rel=1e-5)


def test_mass_matrix_is_symmetric_positive_definite(model: ThreeLP) -> None:
    """The single-support mass matrix is symmetric positive definite; stiffness indefinite."""
    mass = model.axis.mass
    assert np.allclose(mass, mass.T) and np.all(np.linalg.eigvalsh(mass) > 0)
    lam = np.linalg.eigvalsh(model.axis.stiffness)
    assert lam[0] < 0 < lam[1]


def test_disturbance_signs(model: ThreeLP) -> None:
    """A forward torso push accelerates the pelvis forward; the side sign sets σ = ±pw."""
    d = model.disturbance(side=+1, force=(30.0, 0.0))
    assert d[0] == pytest.approx(30.0 * COMAN_LIKE.h1) and d[3] == COMAN_LIKE.pw
    assert model.disturbance(side=-1)[3] == -COMAN_LIKE.pw
    pelvis_acc = (model.F0[Q, D] @ d)[8]
    assert pelvis_acc > 0


def test_step_coordinates() -> None:
    """M M̂ = I, M ignores translations, S and O are involutions."""
    m, m_hat = relative_coordinates(), reconstruction()
    assert np.allclose(m @ m_hat, np.eye(8))
    shift = np.r_[np.tile([0.5, 0.1], 3), np.zeros(6)]
    assert np.allclose(m @ shift, 0.0)
    s = relabel()
    assert np.allclose(s @ s, np.eye(N_XI))
    assert np.allclose(mirror(8) @ mirror(8), np.eye(8))


def test_invalid_parameters_are_rejected() -> None:
    """Non-physical parameters fail with a message naming them."""
    with pytest.raises(ValueError, match="h2"):
        ThreeLPParams(m1=14.2, m2=6.4, h1=0.5, h2=0.6, h3=0.19, pw=0.064)
    with pytest.raises(ValueError, match="masses"):
        ThreeLPParams(m1=14.2, m2=0.0, h1=0.5, h2=0.2, h3=0.19, pw=0.064)
