"""The E-FSM of Lee et al. 2021 (§III, Table I) and its state-transition parameter ε."""

from __future__ import annotations

import math

import pytest

from walkrepro.papers.lee2021.fsm import (
    DS_TO_SSD,
    SSA_TO_DS,
    SSD_TO_SSA,
    FsmInput,
    FsmOutput,
    FsmParams,
    Phase,
    capture_point,
    desired_cop_double_support,
    desired_cop_single_support,
    epsilon,
    fsm_step,
    transition_distance,
    weight_shift_cop,
)

#: §V-B's ζ, r, Δx_p^des, d^thr; Table I's ẋ_m ≈ 0 as EfsmParams.v_stop; with ε.
P = FsmParams(zeta=0.03, r=0.08, dxp=0.0007, d_thr=0.01, v_stop=0.005, use_epsilon=True)


class EventFsm:
    """The compiled E-FSM step with its state (phase, x_p^des) kept between ticks."""

    def __init__(self, params: FsmParams, start: Phase, xp_start: float = 0.0) -> None:
        self.params, self.phase, self.xp_des = params, start, xp_start

    def step(self, inp: FsmInput) -> FsmOutput:
        """One control period; the phase of the output as a Phase."""
        out = fsm_step(int(self.phase), self.xp_des, inp, self.params)
        self.phase, self.xp_des = Phase(out.phase), out.xp_des
        return out._replace(phase=self.phase)


def test_capture_point_eq2() -> None:
    """x_CP = sqrt(z/g) ẋ + x (Eq. 2)."""
    assert capture_point(0.1, 0.5, 0.81) == pytest.approx(0.1 + math.sqrt(0.81 / 9.81) * 0.5)


def test_eq3_support_centre_when_com_is_far() -> None:
    """Eq. (3): x_p^des is the support centre while x_m > ζ."""
    assert desired_cop_single_support(0.05, 0.03) == 0.0


def test_eq3_zeta_behind_com_when_close() -> None:
    """Eq. (3): x_p^des = x_m − ζ once x_m ≤ ζ, so the CoP stays ζ behind the CoM."""
    assert desired_cop_single_support(0.01, 0.03) == pytest.approx(-0.02)
    assert desired_cop_single_support(-0.04, 0.03) == pytest.approx(-0.07)


def test_eq4_steps_then_snaps() -> None:
    """Eq. (4): x_p^des moves by Δx_p^des toward x_s and snaps onto it when within one step."""
    assert desired_cop_double_support(0.0, 0.2, 0.0007) == pytest.approx(0.0007)
    assert desired_cop_double_support(0.3, 0.2, 0.0007) == pytest.approx(0.2993)
    assert desired_cop_double_support(0.1995, 0.2, 0.0007) == 0.2


def test_epsilon_ramp() -> None:
    """ε is 0 for d ≤ 0, d/d_thr in between and 1 beyond d_thr (§IV-B)."""
    assert epsilon(-0.01, 0.01) == 0.0
    assert epsilon(0.0, 0.01) == 0.0
    assert epsilon(0.005, 0.01) == pytest.approx(0.5)
    assert epsilon(0.02, 0.01) == 1.0


def test_distance_reaches_zero_at_termination() -> None:
    """d is zero exactly at the SSA (x_CP = x_s − r) and DS (x_p^des = x_s) criteria."""
    assert transition_distance(int(Phase.SSA), 0.25, 0.0, 0.25 - P.r, P.r) == pytest.approx(0.0)
    assert transition_distance(int(Phase.DS), 0.25, 0.25, 0.0, P.r) == 0.0
    assert math.isinf(transition_distance(int(Phase.SSD), 0.25, 0.0, 0.0, P.r))


def test_ssd_ends_when_com_stops() -> None:
    """SSD holds while the CoM moves toward the support foot and ends when ẋ_m ≈ 0."""
    fsm = EventFsm(P, start=Phase.SSD)
    assert fsm.step(FsmInput(0.1, -0.2, 0.05, 0.25)).phase is Phase.SSD
    out = fsm.step(FsmInput(0.08, 0.0, 0.08, 0.25))
    assert out.phase is Phase.SSA
    assert out.transitions == SSD_TO_SSA


def test_ssa_ends_when_cp_reaches_swing_foot_minus_r() -> None:
    """SSA holds until x_CP ≥ x_s − r, whatever time passes (no clock)."""
    fsm = EventFsm(P, start=Phase.SSA)
    for _ in range(10000):
        assert fsm.step(FsmInput(0.08, 0.0, 0.08, 0.25)).phase is Phase.SSA
    out = fsm.step(FsmInput(0.12, 0.2, 0.25 - P.r, 0.25))
    assert out.phase is Phase.DS and out.transitions == SSA_TO_DS


def test_ds_moves_cop_and_switches_support() -> None:
    """DS ramps x_p^des to x_s at Δx_p^des per tick, then switches to SSD of the next step."""
    fsm = EventFsm(P, start=Phase.DS, xp_start=0.0)
    x_s = 0.07
    ticks = 0
    while True:
        out = fsm.step(FsmInput(0.1, 0.1, 0.2, x_s))
        ticks += 1
        if out.transitions & DS_TO_SSD:
            break
        assert out.phase is Phase.DS
    assert abs(ticks - x_s / P.dxp) <= 1.0
    assert out.phase is Phase.SSD and out.xp_des == x_s


def test_epsilon_falls_to_zero_before_ds_ends() -> None:
    """With ε, the DS reference wrench fades out over the last d_thr of the CoP ramp."""
    fsm = EventFsm(P, start=Phase.DS, xp_start=0.0)
    eps = []
    while True:
        out = fsm.step(FsmInput(0.1, 0.1, 0.2, 0.05))
        eps.append(out.epsilon)
        if out.transitions & DS_TO_SSD:
            break
    assert eps[0] == 1.0 and eps[-1] == 0.0
    assert all(a >= b for a, b in zip(eps, eps[1:], strict=False))


def test_without_epsilon_it_stays_one() -> None:
    """The ablation (use_epsilon false) keeps ε ≡ 1 (§VI-D1)."""
    fsm = EventFsm(P._replace(use_epsilon=False), start=Phase.DS, xp_start=0.0)
    outs = [fsm.step(FsmInput(0.1, 0.1, 0.2, 0.01)) for _ in range(20)]
    assert all(o.epsilon == 1.0 for o in outs)


def test_one_tick_can_pass_ssd_and_ssa() -> None:
    """A stopped CoM whose capture point already reaches x_s − r goes SSD → SSA → DS in one
    tick (Table I's criteria are checked in order), and x_p^des then follows Eq. (4)."""
    out = fsm_step(int(Phase.SSD), 0.01, FsmInput(0.1, 0.0, 0.2, 0.25), P)
    assert out.transitions == SSD_TO_SSA | SSA_TO_DS
    assert out.phase == Phase.DS and out.xp_des == pytest.approx(0.01 + P.dxp)
    assert out.d == pytest.approx(0.25 - out.xp_des) and out.epsilon == 1.0


def test_weight_shift_drives_the_capture_point_onto_the_support_foot() -> None:
    """The lab's start-up law (fsm.weight_shift_cop) on the LIPM: over a 1.0 s shift the
    capture point goes from between the feet to the first support foot's centre x_s."""
    z, dt, x_s = 0.866, 0.0005, 0.205
    omega = math.sqrt(9.81 / z)
    x, xd, n = 0.1025, 0.0, 2000
    for k in range(n):
        xp = weight_shift_cop(capture_point(x, xd, z), x_s, (n - k - 1) * dt, z)
        assert 0.0 <= xp <= x_s  # between the two sole centres
        xd += omega**2 * (x - xp) * dt
        x += xd * dt
    assert capture_point(x, xd, z) == pytest.approx(x_s, abs=0.01)
    assert x > 0.13  # the CoM has moved toward the support foot


def test_weight_shift_without_time_left_is_the_support_centre() -> None:
    """No time left (b = 1): the CoP is the support foot's centre, not a division by 0."""
    assert weight_shift_cop(0.15, 0.205, 0.0, 0.866) == 0.205


def test_weight_shift_far_from_its_target_is_clipped() -> None:
    """A capture point far short of x_s with little time left asks for a CoP beyond the
    other foot: it is clipped to that foot's centre (0), never outside the two centres."""
    assert weight_shift_cop(0.10, 0.205, 0.01, 0.866) == 0.0
    assert weight_shift_cop(0.30, 0.205, 0.01, 0.866) == 0.205
