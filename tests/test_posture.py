"""The standing posture controller's compiled gravity-relief algebra."""

from __future__ import annotations

import numpy as np

from walkrepro.controllers.posture import feet_gravity_torque


def test_feet_gravity_torque_equals_the_minimum_norm_formula() -> None:
    """For random sole Jacobians and gravity vectors, the kernel gives S (g − J_cᵀ λ) with the
    minimum-norm λ of J_c,baseᵀ λ = g_base (numpy's pinv), and the base rows balance."""
    rng = np.random.default_rng(4)
    for nv in (18, 28):
        jc = rng.normal(size=(12, nv))
        g = rng.normal(size=nv)
        lam = np.linalg.pinv(jc[:, :6].T) @ g[:6]
        expected = g[6:] - jc[:, 6:].T @ lam
        tau = feet_gravity_torque(jc, g)
        assert tau.shape == (nv - 6,)
        assert np.allclose(tau, expected, rtol=1e-10, atol=1e-10)
        assert np.allclose(jc[:, :6].T @ lam, g[:6])
