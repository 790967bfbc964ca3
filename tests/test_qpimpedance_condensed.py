"""Tests of the active_set solver of the §III-D QP, ξ̈ eliminated (condensed.py), against numpy,
scipy and a QP library."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

from walkrepro.papers.jo_oh.centroidal_qp import (
    CentroidalTasks,
    Dynamics,
    QPSolution,
    QPWeights,
    SupportContacts,
    contact_wrench_basis,
    empty_eliminated,
    empty_qp,
    friction_basis,
    qp_records,
    solve_centroidal,
    solve_with_qpsolvers,
    stack_of,
)
from walkrepro.papers.jo_oh.condensed import (
    cholesky_in_place,
    nonnegative_qp,
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
def test_solve_centroidal_equals_daqp_on_a_random_problem(n_feet: int) -> None:
    """The compiled build + active set + Eq. (9) finds DAQP's minimiser (an exact dual active
    set, through qpsolvers) of the same built problem, on random dynamics and tasks."""
    rng = np.random.default_rng(n_feet)
    nv = 28
    mass = np.asfortranarray(_spd(rng, nv, 1.0))  # Pinocchio's M is column-major
    nle = 10.0 * rng.standard_normal(nv)
    nle[2] = 500.0  # weight on the base, so the feet push
    corners = np.array([[sx * 0.12, sy * 0.065, 0.0] for sx in (1, -1) for sy in (1, -1)])
    local = contact_wrench_basis(np.eye(3), corners, friction_basis(0.6, 4))
    contacts = SupportContacts(
        rng.standard_normal((n_feet, 6, nv)), rng.standard_normal((n_feet, 6)),
        np.array([local] * n_feet),
    )  # fmt: skip

    def task(rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return rng.standard_normal((rows, nv)), rng.standard_normal(rows), np.full(rows, 4.0)

    stack = stack_of(task(3), task(3), task(9), task(6))
    tasks = CentroidalTasks(rng.standard_normal(6), np.ones(6), stack)
    weights = QPWeights(1e-4, 1e-6)
    dynamics = Dynamics(mass, nle)
    problem = empty_qp(nv, 16 * n_feet, n_feet, weights.force)
    solution = QPSolution(np.zeros(nv + 16 * n_feet), np.zeros((n_feet, 6)), np.zeros(nv - 6))
    eliminated = empty_eliminated(nv, 16 * n_feet)
    records = qp_records(dynamics, tasks, contacts, weights, problem, eliminated, solution)
    assert solve_centroidal(records) > 0
    ref = solve_with_qpsolvers(problem, "daqp")  # the problem solve_centroidal built
    assert ref is not None
    np.testing.assert_allclose(solution.x, ref, rtol=1e-6, atol=1e-6)
    accel, beta = ref[:nv], ref[nv:]
    wrenches = np.array([local @ beta[16 * k : 16 * (k + 1)] for k in range(n_feet)])
    tau = (
        mass[6:] @ accel
        + nle[6:]
        - sum(j[:, 6:].T @ w for j, w in zip(contacts.jacobians, wrenches, strict=True))
    )
    np.testing.assert_allclose(solution.wrenches, wrenches, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(solution.tau, tau, rtol=1e-6, atol=1e-5)
