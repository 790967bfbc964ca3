"""Physical ranges of controller parameters: a value outside is a typo or a unit slip.

Every numeric field of a controller's ``Params`` model has a lower and an upper bound
(pydantic ``Field(ge=, gt=, le=, lt=)``); ``tests/test_fuzz_spec.py`` checks that none lacks
one. Each bound follows from the parameter's meaning on the papers' robots (DYROS RED
89.6 kg with a 0.30 × 0.15 m sole, COMAN ≈ 28 kg with a 0.19 × 0.09 m sole, the KIST
humanoid 57 kg; every leg shorter than 1 m), never from a walking result, and lies beyond
every value the papers, the calibrations and walkrepro's specs and maps use. Bounds specific
to one parameter are in that field's description.
"""

from __future__ import annotations

from walkrepro.specs.models import (
    MAX_CONTROL_PERIOD,
    MAX_DURATION,
    MAX_FORCE,
    MAX_FRICTION,
    MAX_TORQUE,
)

__all__ = [
    "MAX_BANDWIDTH",
    "MAX_CONTROL_PERIOD",
    "MAX_COUNT",
    "MAX_DAMPING",
    "MAX_DURATION",
    "MAX_FORCE",
    "MAX_FRICTION",
    "MAX_JOINT_DAMPING",
    "MAX_JOINT_STIFFNESS",
    "MAX_LENGTH",
    "MAX_PHASE_TIME",
    "MAX_SPEED",
    "MAX_STIFFNESS",
    "MAX_TORQUE",
    "MAX_WEIGHT",
]

#: Largest task bandwidth ω [rad/s]: a loop of period Δt tracks nothing faster than
#: ω Δt ≈ 1, and the papers' controllers run at 1–2 kHz (Paper III: 1 kHz).
MAX_BANDWIDTH = 1e3
#: Largest task stiffness k_p = ω² [1/s²] (:data:`MAX_BANDWIDTH` squared).
MAX_STIFFNESS = MAX_BANDWIDTH**2
#: Largest task damping k_v = 2 ζ ω [1/s] at ζ = 1 and :data:`MAX_BANDWIDTH`.
MAX_DAMPING = 2.0 * MAX_BANDWIDTH
#: Largest joint stiffness [Nm/rad]: a stiff servo's 1e6 (``specs.models.MAX_POSITION_GAIN``).
MAX_JOINT_STIFFNESS = 1e6
#: Largest joint damping [Nms/rad]: critical damping 2 √(k I) of :data:`MAX_JOINT_STIFFNESS`
#: on a 25 kg m² inertia, more than a whole leg's about its hip.
MAX_JOINT_DAMPING = 1e4
#: Largest length [m] of a step, a swing lift, a foot spacing or a footstep correction: no
#: leg of the papers' robots reaches 1 m.
MAX_LENGTH = 1.0
#: Largest speed [m/s]: walking ends at Froude number 1, v = √(g l) ≈ 3.1 m/s for a 1 m leg.
MAX_SPEED = 3.0
#: Longest step or gait phase [s]: the papers' steps last 0.4–0.7 s; over 5 s a linear
#: inverted pendulum of under 1 m height diverges by more than e^15: no step lasts so long.
MAX_PHASE_TIME = 5.0
#: Most steps, samples or ramp steps: one simulated hour (:data:`MAX_DURATION`) holds fewer
#: than 10 000 of the papers' 0.4 s steps.
MAX_COUNT = 10_000
#: Largest QP or preview weight [-]: above 1e8 a weight's ratio to the 1e-6 regularisation
#: passes 1e14, near double precision's 1/ε ≈ 4.5e15, and the solve loses its digits.
MAX_WEIGHT = 1e8
