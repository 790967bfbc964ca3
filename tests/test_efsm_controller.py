"""Tests of the E-FSM controller's swing-foot force (Lee et al. 2021, §IV-C and §V-B)."""

from __future__ import annotations

import numpy as np

from walkrepro.controllers.efsm.controller import EfsmController, EfsmParams
from walkrepro.controllers.efsm.fsm import Phase


def _controller(**params: object) -> EfsmController:
    ctrl = EfsmController.__new__(EfsmController)
    ctrl._p = EfsmParams(**params)
    return ctrl


def _coupled_lambda(seed: int = 0) -> np.ndarray:
    """A task-2 inertia (3 CoM/yaw rows + 6 swing rows) with linear–angular coupling."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(9, 9))
    lam = a @ a.T + 9.0 * np.eye(9)
    lam[3:6, 3:6] += 10.0 * np.eye(3)  # the swing foot's mass [kg]
    return lam


def test_saturated_force_keeps_orientation_acceleration() -> None:
    """With the force rows saturated, the swing foot still gets its orientation acceleration."""
    lam = _coupled_lambda()
    acc = np.r_[0.1, -0.2, 0.05, 20.0, -15.0, 5.0, 0.3, -0.2, 0.1]  # large linear ẍ*
    ctrl = _controller(fs_max_force=30.0, fs_max_moment=1e3)
    f2 = ctrl._task2_force(lam, acc, False, 1.0, Phase.SSD)
    fs = f2[3:]
    assert np.all(np.abs(fs[:3]) <= 30.0 + 1e-9)
    acc_s = np.linalg.solve(lam[3:, 3:], fs - lam[3:, :3] @ acc[:3])
    np.testing.assert_allclose(acc_s[3:], acc[6:], atol=1e-9)


def test_unsaturated_force_is_lambda_times_acceleration() -> None:
    """Below the bound, F_s is Λ ẍ* (Eq. 6) whichever saturation is used."""
    lam = _coupled_lambda(1)
    acc = np.r_[0.1, -0.2, 0.05, 0.2, -0.1, 0.1, 0.3, -0.2, 0.1]
    for decoupled in (True, False):
        ctrl = _controller(fs_max_force=1e4, fs_max_moment=1e4, fs_decoupled_saturation=decoupled)
        f2 = ctrl._task2_force(lam, acc, False, 1.0, Phase.SSD)
        np.testing.assert_allclose(f2[3:], lam[3:] @ acc, atol=1e-9)


def test_epsilon_scales_swing_force_in_ssa() -> None:
    """ε multiplies F_s in SSA (§IV-C): ε = 0 gives no swing-foot force."""
    lam = _coupled_lambda(2)
    acc = np.r_[0.1, -0.2, 0.05, 2.0, -1.0, 1.0, 0.3, -0.2, 0.1]
    f2 = _controller()._task2_force(lam, acc, False, 0.0, Phase.SSA)
    np.testing.assert_allclose(f2[3:], 0.0, atol=1e-12)
