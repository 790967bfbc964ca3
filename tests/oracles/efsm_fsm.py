"""The event-based finite-state machine of Lee et al. 2021, §III and Table I.

Everything here is one-dimensional along the x-axis of the frame O_w (origin at the
support-foot centre, x toward the swing foot's ground projection). No clock appears in
any transition: each state ends on an event of the measured state (Table I).

A test oracle, not part of the package: the controller's tick runs the same E-FSM compiled,
``walkrepro.papers.lee2021.kernels.fsm_step`` (its inputs and parameters are the records
``kernels.FsmInput`` and ``kernels.FsmParams``, with the fields of :class:`FsmInput` and
:class:`FsmParams` here, in the same order), which ``tests/test_efsm_kernels.py`` compares
with :meth:`EventFsm.step`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from walkrepro.papers.lee2021.fsm import Phase


@dataclass(frozen=True)
class FsmParams:
    """E-FSM parameters (§V-B).

    Attributes:
        zeta: margin ζ of law L1 [m].
        r: margin r of law L2 [m].
        dxp: Δx_p^des, desired-CoP step per control period in DS [m].
        d_thr: threshold d^thr of the state-transition parameter ε [m].
        v_stop: |ẋ_m| below which the CoM counts as stopped (ẋ_m ≈ 0) [m/s].
        use_epsilon: False gives ε ≡ 1 (the ablation of §VI-D1).
    """

    zeta: float = 0.03
    r: float = 0.08
    dxp: float = 0.0007
    d_thr: float = 0.01
    v_stop: float = 0.005
    use_epsilon: bool = True


def capture_point(x_m: float, xd_m: float, z_m0: float, g: float = 9.81) -> float:
    """Capture point x_CP = sqrt(z_m0 / g) ẋ_m + x_m, Eq. (2) [m]."""
    return math.sqrt(z_m0 / g) * xd_m + x_m


def desired_cop_single_support(x_m: float, zeta: float) -> float:
    """Desired CoP in SSD and SSA, Eq. (3) [m]: the support centre, or ζ behind the CoM."""
    return 0.0 if x_m > zeta else x_m - zeta


def desired_cop_double_support(xp_prev: float, x_s: float, dxp: float) -> float:
    """Desired CoP in DS, Eq. (4) [m]: steps of Δx_p^des from xp_prev toward x_s."""
    delta = x_s - xp_prev
    if abs(delta) > dxp:
        return xp_prev + math.copysign(dxp, delta)
    return x_s


def transition_distance(phase: Phase, x_s: float, xp_des: float, x_cp: float, r: float) -> float:
    """Distance d to the termination criterion (§IV-B) [m]; +inf in SSD (ε = 1).

    In DS d = x_s − x_p^des. In SSA the paper prints d = (x_s − ζ) − x_CP, which stays
    ≥ r − ζ > d^thr when SSA ends (x_CP ≥ x_s − r), so ε could never fall; we use the
    SSA termination criterion itself, d = (x_s − r) − x_CP, which reaches 0 exactly when
    SSA ends, as the text requires ("altered at the instant when d ≤ 0").
    """
    if phase is Phase.DS:
        return x_s - xp_des
    if phase is Phase.SSA:
        return (x_s - r) - x_cp
    return math.inf


def epsilon(d: float, d_thr: float) -> float:
    """State-transition parameter ε(d) ∈ [0, 1] (§IV-B)."""
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


class FsmOutput(NamedTuple):
    """What the E-FSM decides each tick.

    Attributes:
        phase: state after this tick's transitions.
        xp_des: desired CoP x_p^des along x of O_w [m].
        epsilon: state-transition parameter ε.
        d: distance to the termination criterion [m].
        switched_support: True when DS ended this tick (the feet swap roles).
        transitions: the (old, new) phase changes that happened this tick.
    """

    phase: Phase
    xp_des: float
    epsilon: float
    d: float
    switched_support: bool
    transitions: tuple[tuple[Phase, Phase], ...]


class EventFsm:
    """SSD → SSA → DS → SSD … with time-independent termination criteria (Table I)."""

    def __init__(self, params: FsmParams, start: Phase = Phase.DS, xp_start: float = 0.0):
        """Start in ``start`` (Table I: the first footstep starts in DS) with x_p^des."""
        self.params = params
        self.phase = start
        self.xp_des = xp_start

    def step(self, inp: FsmInput) -> FsmOutput:
        """Advance one control period; x_p^des is expressed in the O_w of ``inp``.

        When DS ends, the returned ``xp_des`` is still the old frame's (= x_s, the new
        support centre); the caller re-expresses it in the new O_w (where it is 0).
        """
        p = self.params
        transitions: list[tuple[Phase, Phase]] = []
        switched = False
        # Termination criteria of the current state (Table I).
        if self.phase is Phase.SSD and inp.xd_m >= -p.v_stop:
            transitions.append((Phase.SSD, Phase.SSA))
            self.phase = Phase.SSA
        if self.phase is Phase.SSA and inp.x_cp >= inp.x_s - p.r:
            transitions.append((Phase.SSA, Phase.DS))
            self.phase = Phase.DS
        # Desired CoP of the (possibly new) state: Eq. (3) or Eq. (4).
        if self.phase is Phase.DS:
            self.xp_des = desired_cop_double_support(self.xp_des, inp.x_s, p.dxp)
        else:
            self.xp_des = desired_cop_single_support(inp.x_m, p.zeta)
        d = transition_distance(self.phase, inp.x_s, self.xp_des, inp.x_cp, p.r)
        eps = epsilon(d, p.d_thr) if p.use_epsilon else 1.0
        if self.phase is Phase.DS and abs(inp.x_s - self.xp_des) <= 0.0:
            # DS ends when x_p^des ≈ x_s: the swing foot becomes the support foot.
            transitions.append((Phase.DS, Phase.SSD))
            self.phase = Phase.SSD
            switched = True
        return FsmOutput(self.phase, self.xp_des, eps, d, switched, tuple(transitions))

    def reframe(self, xp_des: float) -> None:
        """Re-express the stored x_p^des after O_w moved [m]."""
        self.xp_des = xp_des
