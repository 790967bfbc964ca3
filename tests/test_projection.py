"""Time-projection control and its look-up tables (Paper II, Eqs. 15-18, Fig. 13)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from walkrepro.papers.faraji.dlqr import Dlqr, default_weights
from walkrepro.papers.faraji.gait import PeriodicGait
from walkrepro.papers.faraji.projection import (
    SAGITTAL,
    TimeProjection,
    attack_angle,
    projection_gains,
    truncate_footstep,
)
from walkrepro.papers.faraji.threelp import (
    D,
    Q,
    ThreeLP,
    ThreeLPParams,
    U,
    mirror,
    reconstruction,
    relative_coordinates,
)

# COMAN-like parameters of note 3lp.md §8; pushes act at the torso CoM (h4 = h3).
COMAN_LIKE = ThreeLPParams(m1=14.2, m2=6.4, h1=0.524, h2=0.232, h3=0.190, pw=0.064, h4=0.190)
T, V, W, N = 0.4, 0.3, 0.25, 100
M = relative_coordinates()

#: A controller maps (phase time [s], error e(t), error at the step start) to δu (4,).
Policy = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


@pytest.fixture(scope="module")
def model() -> ThreeLP:
    return ThreeLP(COMAN_LIKE)


@pytest.fixture(scope="module")
def gait(model: ThreeLP) -> PeriodicGait:
    return PeriodicGait.solve(model, V, T, W)


@pytest.fixture(scope="module")
def dlqr(model: ThreeLP) -> Dlqr:
    return Dlqr.solve(model, T)


@pytest.fixture(scope="module")
def tp(model: ThreeLP, gait: PeriodicGait, dlqr: Dlqr) -> TimeProjection:
    return TimeProjection.build(model, gait, dlqr, n_samples=N)


@pytest.fixture(scope="module")
def tick_maps(model: ThreeLP) -> list[np.ndarray]:
    """Φ(t_i, T/N) for the N control ticks of a step (zero-order hold on the parameters)."""
    return [model.propagator(i * T / N, T / N) for i in range(N)]


def simulate(
    model: ThreeLP,
    gait: PeriodicGait,
    tick_maps: list[np.ndarray],
    policy: Policy,
    n_steps: int = 5,
    push_step: int = 1,
    force: float = 30.0,
) -> np.ndarray:
    """3LP walk with a forward torso push during 30-50 % of one step.

    Returns:
        Touchdown errors E[k] = M q − M q̄ (sagittal and lateral), shape (n_steps + 1, 8).
    """
    side, xi = 1, gait.initial(1).copy()
    errors = [M @ xi[Q] - gait.relative_state(0.0, side)]
    for k in range(n_steps):
        e_start = errors[-1]
        for i in range(N):
            t = i * T / N
            e = M @ xi[Q] - gait.relative_state(t, side)
            xi[U] = gait.inputs(side)
            xi[U][:4] += policy(t, e, e_start)
            pushed = k == push_step and 0.3 * T - 1e-9 <= t < 0.5 * T - 1e-9
            xi[D] = model.disturbance(side, force=(force if pushed else 0.0, 0.0))
            xi = tick_maps[i] @ xi
        q = xi[Q].copy()  # touchdown: swap the feet, both at rest
        q[0:2], q[4:6] = q[4:6].copy(), q[0:2].copy()
        q[6:8] = q[10:12] = 0.0
        xi[Q], side = q, -side
        errors.append(M @ xi[Q] - gait.relative_state(0.0, side))
    return np.array(errors)


def test_projection_at_step_start_is_dlqr(tp: TimeProjection, dlqr: Dlqr) -> None:
    """At t = 0 the time projection reduces to the DLQR gain (swing foot at rest)."""
    free = [0, 1, 2, 3, 6, 7]  # the DLQR assumes ḟ = 0; K_tp(0) also handles ḟ ≠ 0
    assert np.allclose(tp.torque_gains[0][:, free], dlqr.gain[:, free], rtol=1e-9, atol=1e-9)


def test_correction_is_constant_without_inter_sample_disturbance(
    model: ThreeLP, dlqr: Dlqr
) -> None:
    """Along an undisturbed step, the correction at any t equals the DLQR one at the start."""
    error = np.random.default_rng(0).normal(size=8) * 0.02
    error[4:6] = 0.0
    du0 = dlqr.correction(error)
    for t in (0.05, 0.13, 0.2, 0.31, 0.38):
        cf = model.closed_form(t)
        e_t = M @ (cf.A @ reconstruction() @ error + cf.B[:, :4] @ du0)
        du_t = -projection_gains(model, dlqr, t).torque @ e_t
        assert np.allclose(du_t, du0, rtol=1e-7, atol=1e-9)


def test_push_recovery_ordering(
    model: ThreeLP,
    gait: PeriodicGait,
    dlqr: Dlqr,
    tp: TimeProjection,
    tick_maps: list[np.ndarray],
) -> None:
    """A 30 N push: open loop grows ≈ 3.7×/step, DLQR acts a step late, TP at once ≈ 4×/step."""
    q_w, _ = default_weights(model)

    def size(errors: np.ndarray) -> np.ndarray:
        return np.sqrt(np.einsum("ki,ij,kj->k", errors, q_w, errors))

    open_loop = size(simulate(model, gait, tick_maps, lambda t, e, e0: np.zeros(4)))
    discrete = size(simulate(model, gait, tick_maps, lambda t, e, e0: dlqr.correction(e0)))
    projected = size(simulate(model, gait, tick_maps, lambda t, e, e0: tp.torque_correction(t, e)))
    # E[k] is the error at the k-th touchdown; the push acts during step 1, so E[2] is the
    # end of the push step.
    assert open_loop[1] < 1e-12 and projected[1] < 1e-12
    assert np.all((open_loop[3:] / open_loop[2:-1] > 3.0) & (open_loop[3:] / open_loop[2:-1] < 6))
    assert discrete[2] == pytest.approx(open_loop[2], rel=1e-9)  # DLQR: no action in the push step
    assert projected[2] < discrete[2]
    assert projected[3] < 0.1 * min(discrete[3], open_loop[3])
    assert projected[4] < discrete[4] < open_loop[4]
    assert np.all(projected[3:] / projected[2:-1] < 0.3)  # shrinks ≈ 4× per step from the push
    assert np.all(discrete[4:] / discrete[3:-1] < 0.3)  # DLQR shrinks only one step later


def test_footstep_gains_stay_bounded_while_torque_gains_blow_up(tp: TimeProjection) -> None:
    """‖K_tp‖ grows by orders of magnitude near touchdown; the footstep gains do not."""
    k_norm = np.linalg.norm(tp.torque_gains, ord=2, axis=(1, 2))
    assert k_norm[int(0.9 * N)] > 100 * k_norm[0]
    assert np.abs(tp.footstep_gains).max() < 10.0
    # With no time left, the touchdown is where the swing foot is: f − s = (p − s) − (p − f).
    assert np.allclose(tp.footstep_gains[-1][0, SAGITTAL], [-1, 1, 0, 0], atol=0.05)


def test_footstep_gain_matches_closed_loop_simulation(
    model: ThreeLP, gait: PeriodicGait, tp: TimeProjection, tick_maps: list[np.ndarray]
) -> None:
    """F(t) e(t) is the touchdown shift of a tick-by-tick time-projection simulation."""
    i0 = 30
    e0 = np.random.default_rng(2).normal(size=8) * 0.02
    xi = np.zeros_like(gait.start)
    xi[Q] = reconstruction() @ e0  # error dynamics: linear, so simulate the error alone
    for i in range(i0, N):
        e = M @ xi[Q]
        xi[U][:4] = tp.torque_correction(i * T / N, e)
        xi = tick_maps[i] @ xi
    assert np.allclose(tp.footstep_adjustment(i0 * T / N, e0), xi[0:2], atol=1e-10)
    assert np.abs(xi[6:8]).max() < 1e-9  # and the foot lands at rest


def test_gains_are_speed_independent_and_mirror_symmetric(
    model: ThreeLP, dlqr: Dlqr, tp: TimeProjection
) -> None:
    """Tables do not depend on the commanded speed, and serve left and right steps alike."""
    other = TimeProjection.build(model, PeriodicGait.solve(model, 0.0, T, W), dlqr, n_samples=N)
    assert np.array_equal(other.torque_gains, tp.torque_gains)
    for k_tp, f in zip(tp.torque_gains[::10], tp.footstep_gains[::10], strict=True):
        assert np.allclose(mirror(4) @ k_tp @ mirror(8), k_tp)
        assert np.allclose(mirror(2) @ f @ mirror(8), f)


def test_interpolation(model: ThreeLP, dlqr: Dlqr, tp: TimeProjection) -> None:
    """Lookups hit the samples exactly, blend linearly between them, and hold past the end."""
    i = 40
    assert np.array_equal(tp.torque_gain(tp.phases[i]), tp.torque_gains[i])
    mid = 0.5 * (tp.phases[i] + tp.phases[i + 1])
    blend = 0.5 * (tp.footstep_gains[i] + tp.footstep_gains[i + 1])
    assert np.allclose(tp.footstep_gain(mid), blend, atol=1e-12)
    exact = projection_gains(model, dlqr, mid).footstep
    assert np.abs(tp.footstep_gain(mid) - exact).max() < 1e-3
    assert np.array_equal(tp.torque_gain(T), tp.torque_gains[-1])
    e = np.ones(8) * 0.01
    du = tp.torque_correction(mid, e)
    assert np.allclose(tp.hip_torque_correction(mid, e), du[:2] + mid * du[2:])


def test_truncation_and_attack_angle() -> None:
    """Footstep adjustments clip at ±15 cm and convert to an attack angle by dividing by h1."""
    assert truncate_footstep(0.4) == pytest.approx(0.15)
    assert truncate_footstep(-0.2) == pytest.approx(-0.15)
    assert truncate_footstep(0.05) == pytest.approx(0.05)
    assert attack_angle(0.0524, COMAN_LIKE.h1) == pytest.approx(0.1)


def test_build_rejects_mismatched_step_times(model: ThreeLP, gait: PeriodicGait) -> None:
    """The gait and the DLQR must share the step time."""
    with pytest.raises(ValueError, match="step time"):
        TimeProjection.build(model, gait, Dlqr.solve(model, 0.5))
