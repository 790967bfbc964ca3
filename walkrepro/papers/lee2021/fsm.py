"""The event-based finite-state machine (E-FSM) of Lee et al. 2021, §III and Table I.

Everything here is one-dimensional along the x-axis of the walking frame O_w (origin at the
support-foot centre, x toward the swing foot's ground projection, §III-A1). No clock
appears in any transition: each state ends on an event of the measured state (Table I).
Compiled with numba: the controller's tick (:func:`.kernels.tick`) calls :func:`fsm_step`.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

import numba

#: Compiled and cached on disk, as the rest of the tick.
_jit = numba.njit(cache=True, error_model="numpy")

#: g of the capture point, Eq. (2) [m/s²].
GRAVITY = 9.81
#: Bits of :func:`fsm_step`'s ``transitions``: the E-FSM transitions of a tick (they happen
#: in this order).
SSD_TO_SSA, SSA_TO_DS, DS_TO_SSD = 1, 2, 4


class Phase(IntEnum):
    """E-FSM states (Table I)."""

    SSD = 0  #: single support, decelerate the CoM
    SSA = 1  #: single support, accelerate the CoM toward the swing foot
    DS = 2  #: double support, move the desired CoP to the swing foot


# The phases as plain ints for the compiled code.
_SSD, _SSA, _DS = int(Phase.SSD), int(Phase.SSA), int(Phase.DS)


@_jit
def capture_point(x_m: float, xd_m: float, z_m0: float) -> float:
    """Capture point x_CP = sqrt(z_m0 / g) ẋ_m + x_m, Eq. (2) [m].

    Args:
        x_m: CoM position [m]; xd_m: CoM velocity [m/s]; z_m0: CoM height [m].
    """
    return math.sqrt(z_m0 / GRAVITY) * xd_m + x_m


@_jit
def weight_shift_cop(x_cp: float, x_s: float, remaining: float, z_m0: float) -> float:
    """Desired CoP of the first DS's weight shift [m], along x of O_w (support centre at 0).

    Not the paper's: the lab's start-up (saga0619/dyros_red @ 281ef7e,
    dyros_red_controller/src/control_base.cpp, mode 15 from line 590, segment 0 of
    ``time_segment`` 1.0 s, line 597; no swing before segment 1, line 693): the capture
    point is driven onto the first support foot, whose centre is x_s here, by the end of
    the segment, ``zmp = 1 / (1 − b) cp_ref − b / (1 − b) cp``, b = exp(ω (T − t)),
    ω = sqrt(g / z) (T − t = ``remaining`` [s]). The CoP is kept between the two sole
    centres, [0, x_s] (the lab clips the ZMP's y at ±0.12 m, 1.8 cm outside its foot
    centre; the bound here is assumed).

    Args:
        x_cp: capture point, Eq. (2) [m]; x_s: the first support foot's centre [m];
        remaining: time left in the shift [s]; z_m0: CoM height [m].
    """
    b = math.exp(math.sqrt(GRAVITY / z_m0) * remaining)
    xp = x_s if b <= 1.0 else (x_s - b * x_cp) / (1.0 - b)
    return min(max(xp, 0.0), x_s)


@_jit
def desired_cop_single_support(x_m: float, zeta: float) -> float:
    """Desired CoP in SSD and SSA, Eq. (3) [m]: the support centre, or ζ behind the CoM
    (laws L1)."""
    return 0.0 if x_m > zeta else x_m - zeta


@_jit
def desired_cop_double_support(xp_prev: float, x_s: float, dxp: float) -> float:
    """Desired CoP in DS, Eq. (4) [m]: steps of Δx_p^des from ``xp_prev`` toward x_s."""
    delta = x_s - xp_prev
    if abs(delta) > dxp:
        return xp_prev + math.copysign(dxp, delta)
    return x_s


@_jit
def transition_distance(phase: int, x_s: float, xp_des: float, x_cp: float, r: float) -> float:
    """Distance d to the termination criterion (§IV-B) [m]; +inf in SSD (ε = 1).

    In DS d = x_s − x_p^des. In SSA the paper prints d = (x_s − ζ) − x_CP, which stays
    ≥ r − ζ > d^thr when SSA ends (x_CP ≥ x_s − r), so ε could never fall; we use the
    SSA termination criterion itself, d = (x_s − r) − x_CP, which reaches 0 exactly when
    SSA ends, as the text requires ("altered at the instant when d ≤ 0").
    """
    if phase == _DS:
        return x_s - xp_des
    if phase == _SSA:
        return (x_s - r) - x_cp
    return math.inf


@_jit
def epsilon(d: float, d_thr: float) -> float:
    """State-transition parameter ε(d) ∈ [0, 1] (§IV-B): 1 beyond d^thr, d / d^thr below
    it, 0 at the termination criterion (d ≤ 0)."""
    if d <= 0.0:
        return 0.0
    if d < d_thr:
        return d / d_thr
    return 1.0


class FsmInput(NamedTuple):
    """What the E-FSM reads each tick, along the x-axis of O_w.

    Attributes:
        x_m: CoM position [m].
        xd_m: CoM velocity [m/s].
        x_cp: capture point, Eq. (2) [m].
        x_s: centre of the swing foot's ground projection [m].
    """

    x_m: float
    xd_m: float
    x_cp: float
    x_s: float


class FsmParams(NamedTuple):
    """E-FSM parameters (§V-B).

    Attributes:
        zeta: margin ζ of law L1 [m].
        r: margin r of law L2 [m].
        dxp: Δx_p^des, the desired-CoP step per control period in DS [m] (Eq. 4).
        d_thr: threshold d^thr of ε [m] (§IV-B).
        v_stop: |ẋ_m| below which the CoM counts as stopped (ẋ_m ≈ 0, Table I) [m/s].
        use_epsilon: False gives ε ≡ 1 (the ablation of §VI-D1).
    """

    zeta: float
    r: float
    dxp: float
    d_thr: float
    v_stop: float
    use_epsilon: bool


class FsmOutput(NamedTuple):
    """What the E-FSM decides each tick.

    Attributes:
        phase: the state after this tick's transitions (:class:`Phase` as int).
        xp_des: the desired CoP x_p^des along x of O_w [m] (Eqs. 3–4).
        epsilon: the state-transition parameter ε.
        d: the distance to the termination criterion [m].
        transitions: this tick's transitions as bits (:data:`SSD_TO_SSA`,
            :data:`SSA_TO_DS`, :data:`DS_TO_SSD`: DS ended, the feet swap roles).
    """

    phase: int
    xp_des: float
    epsilon: float
    d: float
    transitions: int


@_jit
def fsm_step(phase: int, xp_des: float, inp: FsmInput, params: FsmParams) -> FsmOutput:
    """One control period of the E-FSM, SSD → SSA → DS → SSD (Table I).

    When DS ends, the returned ``xp_des`` is still the old frame's (= x_s, the new support
    centre); the caller re-expresses it in the new O_w (where it is 0).

    Args:
        phase: the state before the tick (:class:`Phase` as int).
        xp_des: x_p^des before the tick, in the O_w of ``inp`` [m].
        inp: the CoM, capture point and swing foot (:class:`FsmInput`).
        params: :class:`FsmParams`.
    """
    transitions = 0
    # The termination criteria of the current state (Table I).
    if phase == _SSD and inp.xd_m >= -params.v_stop:  # the CoM stopped (ẋ_m ≈ 0)
        transitions |= SSD_TO_SSA
        phase = _SSA
    if phase == _SSA and inp.x_cp >= inp.x_s - params.r:  # law L2
        transitions |= SSA_TO_DS
        phase = _DS
    # The desired CoP of the (possibly new) state: Eq. (3) or Eq. (4).
    if phase == _DS:
        xp_des = desired_cop_double_support(xp_des, inp.x_s, params.dxp)
    else:
        xp_des = desired_cop_single_support(inp.x_m, params.zeta)
    d = transition_distance(phase, inp.x_s, xp_des, inp.x_cp, params.r)
    eps = epsilon(d, params.d_thr) if params.use_epsilon else 1.0
    if phase == _DS and abs(inp.x_s - xp_des) <= 0.0:
        # DS ends when x_p^des ≈ x_s: the swing foot becomes the support foot.
        transitions |= DS_TO_SSD
        phase = _SSD
    return FsmOutput(phase, xp_des, eps, d, transitions)
