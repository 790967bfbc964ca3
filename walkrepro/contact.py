"""The contact model every experiment stands on: the sole on the floor, and on obstacles.

One material pair for all three papers, with its derivation in ``docs/contact.md``. The
stiffness is the COMAN lab's ground contact model (the Robotran model of COMAN,
NicolasVdN/CoManRobotran @ 0207863b3b71c7e91aeb8de957b5525cb1c59088, ``simu_def.h`` and
``user_ExtForces.c``): one vertical spring per cm² of sole, each ``k_gz`` = 27 818 N/m. Under
a robot's full weight on one sole of area A [m²] the sole's stiffness is k = κ A [N/m], with
κ = k_gz per cm² (:data:`AREAL_STIFFNESS`), and the robot rides on it at ω = √(k / m) [rad/s].

The damping is critical (ζ = 1; a bounce at 0.1 m/s restitutes 0.14): MuJoCo's contact is mass-normalised (every
contact row gets the same ω and ζ, whatever the mass behind it), so the source's
load-proportional damping (Geyer's ``F = k_gz z (1 - ż / v_max)``, ``v_max`` = 0.3 m/s) has no
single ζ: linearised under the whole robot's weight it is g / (2 v_max ω) ≈ 0.04, under a
foot's own mass ≈ 0.2, at a landing of 0.1–0.3 m/s ≈ 0.1–0.3; at 0.04 the coman cannot even
stand (docs/contact.md, "Damping").

``solref`` takes the direct form (−ω², −2ζω) (``tests/test_contact.py`` measures ω and ζ by
a bounce).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from walkrepro.errors import SpecError
from walkrepro.robot import Robot
from walkrepro.spec import ContactSpec

#: Standard gravity [m/s²] (MuJoCo's default ``option.gravity``).
GRAVITY = 9.81
#: The sole/floor pair's stiffness per unit of sole area [N/m³]: ``K_GZ_GCM`` = 27 818 N/m per
#: point of a 1 cm × 1 cm mesh.
AREAL_STIFFNESS = 27818.0 / (0.01 * 0.01)
#: Geyer's ``v_max`` [m/s] in the source's damping law (reported in docs/contact.md, not used
#: by the model: see the module docstring).
DAMPING_VELOCITY = 0.3
#: The contact's damping ratio: critical (module docstring).
DAMPING_RATIO = 1.0
#: MuJoCo's default ``solimp``: the impedance sets how much of the weight shows as penetration,
#: not the contact's dynamics (docs/contact.md).
SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
#: MuJoCo's guidance: a contact's time constant is at least this many timesteps.
MIN_TIMESTEPS_PER_TIME_CONSTANT = 2.0


@dataclass(frozen=True)
class ContactModel:
    """A sole/floor contact as MuJoCo takes it.

    Attributes:
        natural_frequency: ω [rad/s] of the robot on one sole.
        damping_ratio: ζ [-].
        source: ``derived`` (from the material pair) or the spec's stated reason.

    MuJoCo's own parameterisation of the same contact is ``solref`` (1/(ζω), ζ) (up to its
    ``dmax`` scaling); the direct form says what the model is.
    """

    natural_frequency: float
    damping_ratio: float
    source: str = "derived"

    @property
    def time_constant(self) -> float:
        """1/ω [s]."""
        return 1.0 / self.natural_frequency

    @property
    def solref(self) -> tuple[float, float]:
        """MuJoCo ``solref`` in its direct form: (−stiffness [1/s²], −damping [1/s])."""
        w = self.natural_frequency
        return (-w * w, -2.0 * self.damping_ratio * w)

    @property
    def solimp(self) -> tuple[float, ...]:
        return SOLIMP


def geyer_damping_ratio(natural_frequency: float) -> float:
    """ζ of the source's damping linearised at the static penetration under the whole
    robot's weight: g / (2 v_max ω) (for the record; the model is critically damped)."""
    return GRAVITY / (2.0 * DAMPING_VELOCITY * natural_frequency)


def derived_contact(robot: Robot) -> ContactModel:
    """The material pair under ``robot``'s full weight on one sole (docs/contact.md)."""
    length, width = robot.sole_size
    stiffness = AREAL_STIFFNESS * length * width  # [N/m]
    omega = math.sqrt(stiffness / robot.total_mass)
    return ContactModel(omega, DAMPING_RATIO)


def contact_model(robot: Robot, override: ContactSpec | None, timestep: float) -> ContactModel:
    """The contact of a run: derived, or the spec's ``world.contact`` with its reason.

    Raises:
        SpecError: the time constant is below MuJoCo's guidance of two timesteps.
    """
    if override is None:
        model = derived_contact(robot)
    else:
        omega = 1.0 / override.time_constant
        model = ContactModel(omega, override.damping_ratio, override.reason)
    if model.time_constant < MIN_TIMESTEPS_PER_TIME_CONSTANT * timestep:
        raise SpecError(
            f"the contact's time constant 1/ω = {model.time_constant * 1e3:.3g} ms is below "
            f"{MIN_TIMESTEPS_PER_TIME_CONSTANT:g} × sim.timestep ({timestep * 1e3:g} ms), "
            "MuJoCo's guidance; lower sim.timestep or raise world.contact.time_constant"
        )
    return model
