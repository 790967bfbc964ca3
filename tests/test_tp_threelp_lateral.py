"""Lateral 3LP gait of Paper II: the in-place bounce and its hip roll (Paper II, Lateral Plane).

Paper II (Open-Loop Control, Lateral Plane): "Lateral bounces in 3LP are as small as 2.2 cm
total displacement of the pelvis, given the desired step width of 25 cm and step time of
T = 0.4 s. These bounces induce sinusoidal trajectories of about 0.03 rad ≈ 1.7° amplitude in
the hip roll joints."

What is checked here:

1. walkrepro's single-support lateral equations against an independent Newton-Euler
   derivation of the 3LP (massless pelvis at constant height, hips at p ± d·pw, torso held
   upright by the stance hip, legs as pendulums from hip to foot with their mass h2 below the
   hip) and against the first author's own closed form (salmanfaraji/Walking3LP @ 63d55a6,
   maple/get_maple_SS.m, matrix A0, evaluated for his COMAN set anatomy/coman_ratios.m with
   tools/model_geom.m at L = 1 m): they agree to round-off, including the pelvis-offset term
   σ = d·pw (its sign: the swing hip sits at p + d·pw on the swing foot's side).
2. The in-place gait (v = 0, T = 0.4 s, W = 0.25 m, free lateral ankle as in the author's
   tools/solution.m) moves the pelvis 7.7 cm peak to peak on coman_lab's 3LP parameters as the
   controller builds them, and 8.05 cm on the author's COMAN set. Physically: the stance hip is
   an ideal actuator that keeps the pelvis level, so the body falls about the stance *foot*,
   its CoM ≈ W/2 = 12.5 cm from it (the hip offsets cancel in the whole-body moment, note
   ``3lp.md`` §2); a point-mass LIP of height h1 with that lever gives
   2·(W/2)·(1 − 1/cosh(ω T/2)) = 7.2 cm. A pendulum pivoting at the stance hip (≈ 5 cm from
   the foot) would give ≈ 3 cm, but that is not the 3LP.
3. The paper's 2.2 cm and 0.03 rad are therefore not what the 3LP gives at the paper's W and
   T (the 3LP gives 2.2 cm only at W ≈ 7 cm, or at T ≈ 0.2 s). The two paper-band tests are
   strict xfails: a known deviation of the paper's figures from its own model, which turns into
   a failure (XPASS, strict) if the model ever produces them.

Bands from the paper's rounding: "2.2 cm" is given to 0.1 cm, so [2.15, 2.25] cm; "about
0.03 rad" is given to one significant figure (the ≈ 1.7° is its conversion, 0.03 rad =
1.72°), so [0.025, 0.035] rad.

Metrics, in the gait's frame (stance foot at the origin, left swing d = +1, y lateral):

- pelvis bounce: peak-to-peak of the pelvis's lateral world position over a left and the
  mirrored right step, p_y(t) and W_land − p_y(t) for t ∈ [0, T] [m];
- hip roll: the lateral angle of one leg relative to the level pelvis over a full cycle, stance
  then swing: atan((p_y − pw − s_y)/h1) while it stands (hip at p − pw), atan((f_y − p_y −
  pw)/h1) while it swings (hip at p + pw) [rad], positive abduction; amplitude = half its range.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from walkrepro.papers.faraji.gait import PeriodicGait
from walkrepro.papers.faraji.openloop import threelp_params_from_robot
from walkrepro.papers.faraji.threelp import ThreeLP, ThreeLPParams
from walkrepro.sim.robot import load_robot

#: Paper II: step time T [s], step width W [m], in-place speed [m/s].
T, W, V = 0.4, 0.25, 0.0
#: Paper II's bounce "2.2 cm", to 0.1 cm: [m].
PAPER_BOUNCE = (0.0215, 0.0225)
#: Paper II's hip roll amplitude "about 0.03 rad", one significant figure: [rad].
PAPER_HIP_ROLL = (0.025, 0.035)

# The first author's COMAN set: anatomy/coman_ratios.m @ 63d55a6 (mass fraction × M, CoM
# position along the segment, segment length / L, foot height / L), total M = 28.5 kg, L = 1 m
# (the file's r.L), combined as in tools/model_geom.m (h1 = foot height + shank + thigh;
# m1 = trunk + arms + head; leg inertia from cylinders). Masses [kg], lengths [m].
_M = 28.5
_THIGH = (0.89 + 1.02 + 1.7, 0.4033, 0.2269)
_SHANK = (1.4, 0.4165, 0.2522)
_FOOT = (0.66 + 0.72, 0.4633, 0.0451)  # mass, CoM ratio, height
_TRUNK = (6.36 + 0.54 + 0.75, 0.4630, 0.3495)
_UPPERARM = (0.77 + 0.57 + 0.88, 0.5087, 0.1600)
_FOREARM = (1.04, 0.4257, 0.1531)
_PELVIS_HALF_WIDTH = 0.0636


def faraji_coman_params() -> ThreeLPParams:
    """The first author's 3LP set for COMAN (module comment), with leg inertia."""
    (mt, ut, lt), (ms, us, ls), (mf, uf, lf) = _THIGH, _SHANK, _FOOT
    m2 = mt + ms + mf
    centres = (lt * ut, lt + ls * us, lt + ls + lf * uf)  # below the hip [m]
    h2 = (mt * centres[0] + ms * centres[1] + mf * centres[2]) / m2
    inertia = (mt * lt**2 + ms * ls**2 + mf * lf**2) / 12 + sum(
        m * (h2 - c) ** 2 for m, c in zip((mt, ms, mf), centres, strict=True)
    )
    (mk, uk, lk), (mu, uu, lu), (ma, ua, _) = _TRUNK, _UPPERARM, _FOREARM
    m1 = mk + 2 * (mu + ma)  # head and hands have no mass in the set
    h3 = (mk * lk * uk + 2 * mu * (lk - lu * uu) + 2 * ma * (lk - lu - _FOREARM[2] * ua)) / m1
    return ThreeLPParams(
        m1=m1, m2=m2, h1=lf + ls + lt, h2=h2, h3=h3, pw=_PELVIS_HALF_WIDTH, I2=inertia, I3=inertia
    )


@pytest.fixture(scope="module")
def lab_params() -> ThreeLPParams:
    """coman_lab's 3LP parameters, built as the controller builds them (leg inertia on)."""
    return threelp_params_from_robot(load_robot("coman_lab"), leg_inertia=True)


def in_place_gait(params: ThreeLPParams, width: float = W, step_time: float = T) -> PeriodicGait:
    return PeriodicGait.solve(ThreeLP(params), V, step_time, width)


def _trajectory(gait: PeriodicGait, n: int = 801) -> np.ndarray:
    """q̄(t) for a left swing (d = +1) on n samples of [0, T], shape (n, 12)."""
    return np.array([gait.state(t, 1) for t in np.linspace(0.0, gait.step_time, n)])


def lateral_bounce(gait: PeriodicGait) -> float:
    """Peak-to-peak lateral pelvis displacement over a left and a right step [m]."""
    q = _trajectory(gait)
    p_y, landing = q[:, 3] - q[:, 5], q[-1, 1] - q[-1, 5]
    world = np.r_[p_y, landing - p_y]  # the right step mirrors the left about the new stance
    return float(world.max() - world.min())


def hip_roll_amplitude(gait: PeriodicGait) -> float:
    """Half the range of one leg's hip roll over a stance and a swing phase [rad]."""
    q = _trajectory(gait)
    prm = gait.model.params
    p_y, f_y, s_y = q[:, 3], q[:, 1], q[:, 5]
    stance = np.arctan((p_y - prm.pw - s_y) / prm.h1)
    swing = np.arctan((f_y - p_y - prm.pw) / prm.h1)
    leg = np.r_[stance, swing]
    return float((leg.max() - leg.min()) / 2)


def assert_paper_bounce(gait: PeriodicGait) -> None:
    bounce = lateral_bounce(gait)
    lo, hi = PAPER_BOUNCE
    assert lo <= bounce <= hi, f"3LP lateral bounce {bounce * 100:.2f} cm, paper 2.2 cm"


def assert_paper_hip_roll(gait: PeriodicGait) -> None:
    amp = hip_roll_amplitude(gait)
    lo, hi = PAPER_HIP_ROLL
    assert lo <= amp <= hi, f"3LP hip roll amplitude {amp:.4f} rad, paper about 0.03 rad"


# --- 1. the lateral equations ---------------------------------------------------------------


def newton_euler_lateral(
    prm: ThreeLPParams, p: float, f: float, s: float, d: float, hip_x: float, ankle_x: float
) -> tuple[float, float]:
    """(p̈_y, f̈_y) of the lateral 3LP from the body-by-body force and moment balances [m/s²].

    Independent of walkrepro.papers.faraji.threelp. Lateral plane (y, z), moments about x.
    Bodies: torso (m1 at (p, h1 + h3), kept upright by the pelvis torque t1), swing leg (m2 at
    hip + κ(foot − hip), hip at p + d·pw, no ground force, hip torque ``hip_x`` from the
    pelvis), stance leg (m2, hip at p − d·pw, foot fixed at s, ground force F3, ankle torque
    ``ankle_x``, pelvis torque t3 free); massless pelvis: forces and moments sum to zero.
    Torques are the physical x components (the author's H2x, M3x); no external push.
    """
    m1, m2, g, h1, h2, h3 = prm.m1, prm.m2, prm.g, prm.h1, prm.h2, prm.h3
    k = h2 / h1
    hip2, hip3 = p + d * prm.pw, p - d * prm.pw
    z_leg = h1 - h2

    def cross(a: tuple[float, float], b: np.ndarray) -> np.ndarray:
        """x component of a × b for (y, z) vectors, as a row on the unknowns (b is a row pair)."""
        return a[0] * b[1] - a[1] * b[0]

    # unknowns: [p̈, f̈, f1y, f1z, f2y, f2z, f3y, f3z, F3y, F3z, t1, t3]
    n = 12
    e = np.eye(n)
    pdd, fdd = e[0], e[1]
    f1, f2, f3, F3 = (e[2], e[3]), (e[4], e[5]), (e[6], e[7]), (e[8], e[9])
    t1, t3 = e[10], e[11]
    a2 = pdd + (fdd - pdd) * k  # swing-leg CoM acceleration
    a3 = pdd * (1 - k)  # stance-leg CoM acceleration (foot fixed)
    rows, rhs = [], []

    def eq(row: np.ndarray, const: float) -> None:  # row·x + const = 0
        rows.append(row)
        rhs.append(-const)

    eq(f1[0] - m1 * pdd, 0.0)
    eq(f1[1], -m1 * g)
    eq(f2[0] - m2 * a2, 0.0)
    eq(f2[1], -m2 * g)
    eq(f3[0] + F3[0] - m2 * a3, 0.0)
    eq(f3[1] + F3[1], -m2 * g)
    y2, y3 = hip2 + (f - hip2) * k, hip3 + (s - hip3) * k
    # stance leg about its CoM: foot and hip forces, t3, ankle torque, inertia I3 (ω̇ = −p̈/h1)
    eq(
        cross((s - y3, -z_leg), np.array(F3))
        + cross((hip3 - y3, h1 - z_leg), np.array(f3))
        + t3
        + prm.I3 * pdd / h1,
        ankle_x,
    )
    # swing leg about its CoM: hip force, hip torque, inertia I2 (ω̇ = (f̈ − p̈)/h1)
    eq(cross((hip2 - y2, h1 - z_leg), np.array(f2)) - prm.I2 * (fdd - pdd) / h1, hip_x)
    # torso about its CoM: pelvis force at h3 below, t1
    eq(cross((0.0, -h3), np.array(f1)) + t1, 0.0)
    eq(f1[0] + f2[0] + f3[0], 0.0)
    eq(f1[1] + f2[1] + f3[1], 0.0)
    # massless pelvis moments about its centre: reactions of f2, f3 at the hips, −t1, −t3
    eq(
        cross((hip2 - p, 0.0), -np.array(f2)) + cross((hip3 - p, 0.0), -np.array(f3)) - t1 - t3,
        -hip_x,
    )
    x = np.linalg.solve(np.array(rows), np.array(rhs))
    return float(x[0]), float(x[1])


def walkrepro_lateral(
    model: ThreeLP, p: float, f: float, s: float, d: float, hip_x: float, ankle_x: float
) -> tuple[float, float]:
    """(p̈_y, f̈_y) from walkrepro's axis matrices; its lateral torques are −τ_x (module doc)."""
    ax = model.axis
    acc = ax.Cx @ [f, p, s] + ax.Cu @ [-hip_x, -ankle_x] + ax.Cd @ [0.0, d * model.params.pw]
    return float(acc[1]), float(acc[0])


STATES = [  # (p, f, s, d, hip_x, ankle_x) in [m] and [Nm]
    (0.11, 0.25, 0.0, 1.0, 0.0, 0.0),
    (-0.07, -0.21, 0.02, -1.0, 0.0, 0.0),
    (0.03, 0.19, -0.01, 1.0, 2.5, 0.0),
    (0.05, 0.31, 0.0, -1.0, -1.5, 3.0),
]


@pytest.mark.parametrize("state", STATES)
def test_lateral_equations_match_newton_euler(lab_params: ThreeLPParams, state: tuple) -> None:
    for prm in (lab_params, faraji_coman_params()):
        ours = walkrepro_lateral(ThreeLP(prm), *state)
        ref = newton_euler_lateral(prm, *state)
        np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12)


def test_newton_euler_comparison_can_fail(lab_params: ThreeLPParams) -> None:
    """Controlled check: the comparison catches the two frame errors a lateral 3LP can make,
    the pelvis offset on the wrong side (swing hip at p − d·pw) and feet placed relative to
    the pelvis centre instead of the hips (pw = 0 in the dynamics)."""
    state = STATES[0]
    ref = newton_euler_lateral(lab_params, *state)
    flipped = walkrepro_lateral(ThreeLP(lab_params), *state[:3], -state[3], *state[4:])
    no_offset = walkrepro_lateral(ThreeLP(replace(lab_params, pw=0.0)), *state)
    for wrong in (flipped, no_offset):
        with pytest.raises(AssertionError):
            np.testing.assert_allclose(wrong, ref, rtol=1e-9, atol=1e-12)
        assert abs(wrong[1] - ref[1]) > 1.0  # the swing-foot row's σ term: 29.2·pw m/s²


# Walking3LP @ 63d55a6, maple/get_maple_SS.m, A0 (single support, rows ddX_y and ddX2_y),
# evaluated for faraji_coman_params() (no slope, upright torso, r_g = 0). Columns: swing foot
# X2_y, pelvis X_y, stance foot X3_y [1/s²], swing-hip torque H2_x, ankle torque M3_x [1/(kg m)],
# side d [m/s²].
AUTHOR_A0 = {
    "pelvis": (3.05705975, 15.41734835, -18.4744081, -0.03191209, -0.0780869, -0.0564063),
    "swing": (-27.61159281, 20.06158167, 7.55001114, 0.96160707, 0.03191209, 1.69969101),
}


def test_lateral_equations_match_the_authors_closed_form() -> None:
    model = ThreeLP(faraji_coman_params())
    ax, pw = model.axis, model.params.pw
    # walkrepro rows [f, p, s]; its lateral torques are −H2_x, −M3_x; σ = d·pw
    for row, key in ((1, "pelvis"), (0, "swing")):
        ours = (*ax.Cx[row], *(-ax.Cu[row]), ax.Cd[row, 1] * pw)
        np.testing.assert_allclose(ours, AUTHOR_A0[key], rtol=2e-6, atol=2e-8)


# --- 2. the in-place gait: observed values ----------------------------------------------------


def test_in_place_bounce_on_coman_lab(lab_params: ThreeLPParams) -> None:
    """Observed 3LP bounce on coman_lab at the paper's W and T: 7.68 cm, hip roll 0.0763 rad.

    Deterministic model output, pinned to catch drift of the model or the robot's parameters.
    """
    gait = in_place_gait(lab_params)
    assert gait.residual < 1e-12
    assert lateral_bounce(gait) == pytest.approx(0.0768, abs=0.0005)
    assert hip_roll_amplitude(gait) == pytest.approx(0.0763, abs=0.0005)


def test_in_place_bounce_on_the_authors_coman_set() -> None:
    gait = in_place_gait(faraji_coman_params())
    assert lateral_bounce(gait) == pytest.approx(0.0805, abs=0.0005)
    assert hip_roll_amplitude(gait) == pytest.approx(0.0784, abs=0.0005)


def test_bounce_against_the_pendulum_about_the_stance_foot(lab_params: ThreeLPParams) -> None:
    """The 3LP bounce is that of an inverted pendulum about the stance foot with the CoM
    ≈ W/2 from it (7.20 cm for a point mass at h1), not about the stance hip (≈ 3 cm)."""
    gait = in_place_gait(lab_params)
    w = math.sqrt(lab_params.g / lab_params.h1)
    about_foot = 2 * (W / 2) * (1 - 1 / math.cosh(w * T / 2))
    about_hip = 2 * (W / 2 - lab_params.pw) * (1 - 1 / math.cosh(w * T / 2))
    bounce = lateral_bounce(gait)
    assert abs(bounce - about_foot) < 0.1 * about_foot
    assert bounce > 2 * about_hip


def test_pelvis_moves_toward_the_stance_foot(lab_params: ThreeLPParams) -> None:
    """Sign: from W/2 at touchdown the pelvis moves toward the stance foot (y = 0) and back."""
    q = _trajectory(in_place_gait(lab_params))
    p_y = q[:, 3]
    assert p_y[0] == pytest.approx(W / 2, abs=1e-9)
    assert p_y[-1] == pytest.approx(W / 2, abs=1e-9)
    assert p_y.min() < W / 2 - 0.03
    assert np.all(p_y <= W / 2 + 1e-9)


# --- 3. the paper's figures -------------------------------------------------------------------

_PAPER_REASON = (
    "Paper II's 2.2 cm / 0.03 rad are not what the 3LP gives at W = 0.25 m, T = 0.4 s: "
    "walkrepro's lateral equations equal the author's closed form (Walking3LP @ 63d55a6) "
    "and give 7.7 cm and 0.076 rad on coman_lab (8.05 cm on the author's COMAN set); "
    "the 3LP reaches 2.2 cm only at W ≈ 7 cm or T ≈ 0.2 s"
)


@pytest.mark.xfail(strict=True, reason=_PAPER_REASON)
def test_paper_lateral_bounce(lab_params: ThreeLPParams) -> None:
    assert_paper_bounce(in_place_gait(lab_params))


@pytest.mark.xfail(strict=True, reason=_PAPER_REASON)
def test_paper_hip_roll(lab_params: ThreeLPParams) -> None:
    assert_paper_hip_roll(in_place_gait(lab_params))


def test_paper_band_checks_can_pass_and_fail(lab_params: ThreeLPParams) -> None:
    """Controlled check of the paper-band assertions: a 3LP gait whose bounce is 2.2 cm (the
    same model at W = 7.16 cm) passes the bounce band; the paper's W fails both bands; a gait
    at T = 0.25 s (3.4 cm, 0.034 rad) passes the hip-roll band only."""
    assert_paper_bounce(in_place_gait(lab_params, width=0.0716))
    with pytest.raises(AssertionError):
        assert_paper_bounce(in_place_gait(lab_params))
    with pytest.raises(AssertionError):
        assert_paper_hip_roll(in_place_gait(lab_params))
    short = in_place_gait(lab_params, step_time=0.25)
    assert_paper_hip_roll(short)
    with pytest.raises(AssertionError):
        assert_paper_bounce(short)
