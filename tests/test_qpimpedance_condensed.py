"""Tests of the compiled kernels that solve the §III-D QP with ξ̈ eliminated (condensed.py)."""

from __future__ import annotations

import numpy as np
import pytest
from oracles.centroidal_qp import solve_with_library
from scipy.optimize import nnls

from walkrepro.papers.jo_oh.centroidal_qp import (
    Task,
    build_qp,
    contact_wrench_basis,
    friction_basis,
    joint_torques,
)
from walkrepro.papers.jo_oh.condensed import (
    CostRows,
    Dynamics,
    QPSolution,
    QPWeights,
    SupportContacts,
    cholesky_in_place,
    nonnegative_qp,
    solve_centroidal,
    solve_eliminated,
    solve_lower,
    solve_lower_transposed,
    solve_lower_transposed_vector,
    solve_lower_vector,
)


def _spd(rng: np.random.Generator, n: int, floor: float = 1e-3) -> np.ndarray:
    a = rng.standard_normal((n + 3, n))
    return a.T @ a + floor * np.eye(n)


def test_cholesky_and_triangular_solves_equal_numpy() -> None:
    """The hand-written Cholesky factor and triangular solves equal numpy's on random SPD input."""
    rng = np.random.default_rng(0)
    for n in (1, 5, 28):
        a = _spd(rng, n)
        low = a.copy()
        assert cholesky_in_place(low)
        np.testing.assert_allclose(np.tril(low), np.linalg.cholesky(a), atol=1e-10)
        b = rng.standard_normal((n, 3))
        x = b.copy()
        solve_lower(low, x)
        solve_lower_transposed(low, x)
        np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-8, atol=1e-10)
    assert not cholesky_in_place(-np.eye(3))


def test_vector_solves_equal_the_matrix_solves_on_one_column_bit_for_bit() -> None:
    """The one-column triangular solves give solve_lower's and solve_lower_transposed's floats exactly."""
    rng = np.random.default_rng(1)
    for n in (1, 6, 18, 32):
        low = _spd(rng, n)
        assert cholesky_in_place(low)
        low = np.triu(rng.standard_normal((n, n)), 1) + np.tril(low)  # junk above: unread
        b = rng.standard_normal((n, 1))
        for matrix_solve, vector_solve in (
            (solve_lower, solve_lower_vector),
            (solve_lower_transposed, solve_lower_transposed_vector),
        ):
            want, got = b.copy(), b.copy()
            matrix_solve(low, want)
            vector_solve(low, got[:, 0])  # a column view, as the kernels pass it
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("warm", [False, True])
def test_nonnegative_qp_equals_scipy_nnls(seed: int, warm: bool) -> None:
    """The active-set minimiser of ½xᵀHx + gᵀx, x ≥ 0, is scipy's NNLS of the same problem."""
    rng = np.random.default_rng(seed)
    n = 32
    hess = _spd(rng, n, 1e-6)
    grad = 3.0 * rng.standard_normal(n)
    low = np.linalg.cholesky(hess)  # ½‖Lᵀx + L⁻¹g‖² = ½xᵀHx + gᵀx + const
    ref, _ = nnls(low.T, -np.linalg.solve(low, grad), maxiter=1000)
    x = np.abs(rng.standard_normal(n)) if warm else np.zeros(n)
    assert nonnegative_qp(hess, grad, x, 4 * n) > 0
    assert np.all(x >= 0)
    np.testing.assert_allclose(x, ref, atol=1e-7 * max(1.0, np.abs(ref).max()))


def test_eliminated_qp_satisfies_kkt_of_the_full_qp() -> None:
    """ξ̈ and β from the eliminated QP satisfy the full QP's equalities, bounds and stationarity."""
    rng = np.random.default_rng(3)
    nv, ne, nb, w4 = 12, 8, 10, 1e-3
    hess, grad = _spd(rng, nv), rng.standard_normal(nv)
    eq_accel, eq_beta, eq_rhs = (
        rng.standard_normal((ne, nv)),
        rng.standard_normal((ne, nb)),
        rng.standard_normal(ne),
    )
    beta, accel = np.zeros(nb), np.zeros(nv)
    assert solve_eliminated(hess.copy(), grad, eq_accel, eq_beta, eq_rhs, w4, beta, accel) > 0
    np.testing.assert_allclose(eq_accel @ accel + eq_beta @ beta, eq_rhs, atol=1e-9)
    # Stationarity: Pξ̈ + q = Eᵀν for some ν, and W_4β − Fᵀν = μ ≥ 0 with μ β = 0.
    nu = np.linalg.lstsq(eq_accel.T, hess @ accel + grad, rcond=None)[0]
    np.testing.assert_allclose(eq_accel.T @ nu, hess @ accel + grad, atol=1e-8)
    mu = w4 * beta - eq_beta.T @ nu
    assert np.all(beta >= 0) and np.all(mu >= -1e-8)
    np.testing.assert_allclose(mu * beta, 0.0, atol=1e-8)


@pytest.mark.parametrize("n_feet", [1, 2])
def test_solve_centroidal_equals_build_qp_and_proxqp(n_feet: int) -> None:
    """The fused kernel finds build_qp's solution (ProxQP through qpsolvers at 1e-11) and its Eq. (9) torques."""
    rng = np.random.default_rng(n_feet)
    nv = 28
    mass = np.asfortranarray(_spd(rng, nv, 1.0))  # Pinocchio's M is column-major
    nle = 10.0 * rng.standard_normal(nv)
    nle[2] = 500.0  # weight on the base, so the feet push
    jacs = [rng.standard_normal((6, nv)) for _ in range(n_feet)]
    drifts = [rng.standard_normal(6) for _ in range(n_feet)]
    corners = np.array([[sx * 0.12, sy * 0.065, 0.0] for sx in (1, -1) for sy in (1, -1)])
    maps = [contact_wrench_basis(np.eye(3), corners, friction_basis(0.6, 4))] * n_feet
    task = Task("t", rng.standard_normal((9, nv)), rng.standard_normal(9), np.full(9, 4.0))
    b1, w1 = rng.standard_normal(6), np.ones(6)
    support = tuple(range(n_feet))
    contacts = SupportContacts(jacs, drifts, maps)
    problem = build_qp(
        Dynamics(mass, nle), b1, w1, contacts, support, [task], QPWeights(1e-4, 1e-6)
    )
    ref = solve_with_library(problem, "proxqp", eps_abs=1e-11, eps_rel=0.0)
    ref_accel, ref_wrenches = problem.split(ref)
    rows = np.ascontiguousarray(np.vstack([mass[:6], 2.0 * task.jacobian]))
    rhs = np.concatenate([b1, 2.0 * task.target])
    beta, accel = np.zeros(16 * n_feet), np.zeros(nv)
    wrenches, tau = np.zeros((n_feet, 6)), np.zeros(nv - 6)
    stacked = SupportContacts(np.array(jacs), np.array(drifts), np.array(maps))
    solution = QPSolution(beta, accel, wrenches, tau)
    cost = CostRows(rows, rhs)
    assert solve_centroidal(cost, Dynamics(mass, nle), stacked, QPWeights(1e-4, 1e-6), solution) > 0
    np.testing.assert_allclose(accel, ref_accel, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(wrenches, np.array(ref_wrenches), rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(
        tau, joint_torques(mass, nle, ref_accel, jacs, ref_wrenches), rtol=1e-6, atol=1e-5
    )
    np.testing.assert_allclose(problem.solve(), ref, rtol=1e-6, atol=1e-5)
