"""The contact every experiment stands on (the sole on the floor and on obstacles), in one place.

``docs/contact.md`` holds the derivation and the measurements behind it. In short:

- **The contact in force** (:data:`DEFAULT_CONTACT`) is MuJoCo's default, ``solref`` (0.02 s,
  1): a critically damped contact of natural frequency about 50 rad/s. It is an assumption,
  declared here, not a physical model.
- **The sourced contact** (:func:`sourced_contact`; a spec selects it with
  ``world.contact: {sourced: true, reason: ...}``) takes the sole's stiffness from the COMAN lab's
  ground contact model (NicolasVdN/CoManRobotran @ 0207863b3b71c7e91aeb8de957b5525cb1c59088,
  ``SfunctionsR/src_user/simulation_files/simu_def.h``, ``K_GZ_GCM``): one vertical spring of
  27 818 N/m per cm² of sole. Under a robot's full weight m on one sole of area A the robot
  rides on it at ω = √(κ A / m) (374–452 rad/s for the three robots); critically damped.
  It is not in force because MuJoCo's linear, mass-normalised contact cannot carry the
  source's damping law (Geyer's ``F = k z (1 - ż / v_max)``, zero at touchdown): at the
  source's damping linearised under the robot's weight (ζ ≈ 0.04) the robots chatter and
  fall; critically damped, every landing starts with a force step c·v (in a drop of the whole
  robot, 2.2× the source law's peak; on the 4 cm block, 1 ms spikes of 2.5–3.6 kN).
- **A departure** for a whole experiment is ``world.contact`` with its ``reason``: a time
  constant 1/ω [s] and damping ratio, or the sourced contact. An obstacle may carry its own
  ``solref`` with a ``solref_reason``.

MuJoCo's guidance that a contact's time constant be at least two timesteps is enforced.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from walkrepro.errors import SpecError
from walkrepro.sim.robot import Robot
from walkrepro.specs.models import ContactSpec

#: Standard gravity [m/s²] (MuJoCo's default ``option.gravity``).
GRAVITY = 9.81
#: The sole/floor pair's stiffness per unit of sole area [N/m³] in the COMAN lab's ground
#: contact model: ``K_GZ_GCM`` = 27 818 N/m per point of a 1 cm × 1 cm mesh.
AREAL_STIFFNESS = 27818.0 / (0.01 * 0.01)
#: The source's ``V_GZ_MAX_GCM`` [m/s]: Geyer's damping velocity (for the record: the damping
#: law the linear contact cannot carry, docs/contact.md).
DAMPING_VELOCITY = 0.3
#: MuJoCo's default ``solimp``.
SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
#: MuJoCo's guidance: a contact's time constant is at least this many timesteps.
MIN_TIMESTEPS_PER_TIME_CONSTANT = 2.0


@dataclass(frozen=True)
class ContactModel:
    """A contact as MuJoCo takes it.

    Attributes:
        solref: MuJoCo ``solref``: (time constant [s], damping ratio), or in the direct form
            (−stiffness [1/s²], −damping [1/s]) per unit mass.
        time_constant: the contact's time constant [s] (MuJoCo's ``timeconst``, or 1/ω of the
            direct form), the number MuJoCo's two-timestep guidance is about.
        source: what the values rest on.
        solimp: MuJoCo ``solimp``.
    """

    solref: tuple[float, float]
    time_constant: float
    source: str
    solimp: tuple[float, ...] = SOLIMP


#: The contact in force: MuJoCo's default, assumed (see the module docstring).
DEFAULT_CONTACT = ContactModel(
    solref=(0.02, 1.0), time_constant=0.02, source="MuJoCo's default contact, assumed"
)


def spring_damper(natural_frequency: float, damping_ratio: float, source: str) -> ContactModel:
    """A linear contact of natural frequency ω [rad/s] and damping ratio ζ, in MuJoCo's direct
    form (−ω², −2ζω): mass-normalised, so any body on it rides at ω with ζ."""
    w = natural_frequency
    return ContactModel((-w * w, -2.0 * damping_ratio * w), 1.0 / w, source)


def sourced_natural_frequency(robot: Robot) -> float:
    """ω [rad/s] of ``robot``'s full weight on one sole with the source's areal stiffness."""
    length, width = robot.sole_size
    return math.sqrt(AREAL_STIFFNESS * length * width / robot.total_mass)


def geyer_damping_ratio(natural_frequency: float) -> float:
    """ζ of the source's damping law linearised at the static penetration under the whole
    robot's weight: g / (2 v_max ω)."""
    return GRAVITY / (2.0 * DAMPING_VELOCITY * natural_frequency)


def sourced_contact(robot: Robot, damping_ratio: float = 1.0) -> ContactModel:
    """The sole's sourced stiffness under ``robot``'s weight on one sole (docs/contact.md)."""
    omega = sourced_natural_frequency(robot)
    return spring_damper(omega, damping_ratio, "the COMAN lab's sole stiffness (docs/contact.md)")


def contact_model(robot: Robot, override: ContactSpec | None, timestep: float) -> ContactModel:
    """The contact of a run: :data:`DEFAULT_CONTACT`, or the spec's ``world.contact``.

    Raises:
        SpecError: the time constant is below MuJoCo's guidance of two timesteps.
    """
    if override is None:
        model = DEFAULT_CONTACT
    elif override.sourced:
        model = sourced_contact(robot, override.damping_ratio)
    else:
        assert override.time_constant is not None  # ContactSpec's validation
        model = spring_damper(1.0 / override.time_constant, override.damping_ratio, override.reason)
    if model.time_constant < MIN_TIMESTEPS_PER_TIME_CONSTANT * timestep:
        raise SpecError(
            f"the contact's time constant {model.time_constant * 1e3:.3g} ms is below "
            f"{MIN_TIMESTEPS_PER_TIME_CONSTANT:g} × sim.timestep ({timestep * 1e3:g} ms), "
            "MuJoCo's guidance; lower sim.timestep or raise world.contact.time_constant"
        )
    return model
