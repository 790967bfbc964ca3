"""The leg joints Paper II's controller addresses, found by name in the robot model.

The controller works on the *leg vector*: the twelve angles the leg IK returns
(:meth:`~.openloop.LegIk.solve_level`), the left leg's six joints then the right leg's, each
leg in actuator order. It needs to know where a few named joints sit in it (the hip pitch
for the attack angle and Eq. 24's hip switch, the knee for Eq. 21's spring compensation,
the ankle pitch for the stance-ankle push-off) and which actuators the leg vector drives.
:func:`leg_joints` reads all of it once, at reset, from the joints' names and the IK's leg
chains (walked from each sole frame up to the pelvis in the Pinocchio model), so nothing in
the controller types an index.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from walkrepro.errors import UnknownNameError
from walkrepro.papers.faraji.ik import SIDES, LegGeometry
from walkrepro.sim.robot import Robot

#: Joint names of a leg, without the side prefix (``l_hip_pitch``, ``r_knee``, ...).
HIP_PITCH, KNEE, ANKLE_PITCH = "hip_pitch", "knee", "ankle_pitch"
#: The torso's roll joint, counter-rolled against the pelvis roll (Eq. 22).
WAIST_ROLL = "waist_roll"
#: Leg indices in (left, right) pairs: the filters' and the loads' order.
LEFT, RIGHT = 0, 1


class Sides(NamedTuple):
    """One joint of each leg: its position in the leg vector, or an actuator index."""

    left: int
    right: int


class LegJoints(NamedTuple):
    """Where Paper II's controller finds its joints (built at reset by :func:`leg_joints`)."""

    actuators: slice | np.ndarray
    """Actuator indices of the leg vector's twelve entries, a slice when contiguous; indexes
    ``ctrl``, ``joint_pos`` and the robot's per-joint arrays."""
    actuator_list: tuple[int, ...]
    """The same as plain ints, shape (12,)."""
    legs: tuple[tuple[int, ...], tuple[int, ...]]
    """Positions of each leg's six joints in the leg vector, (left, right)."""
    leg_of: tuple[int, ...]
    """The leg (:data:`LEFT` or :data:`RIGHT`) of each leg-vector entry, shape (12,)."""
    hip_pitch: Sides
    """Hip pitch joints' positions in the leg vector."""
    knee: Sides
    """Knee joints' positions in the leg vector."""
    ankle_pitch: Sides
    """Ankle pitch joints' positions in the leg vector."""
    sagittal: tuple[tuple[int, int, int], tuple[int, int, int]]
    """Each leg's sagittal spring joints (hip pitch, knee, ankle pitch), leg-vector positions."""
    hip_pitch_actuator: Sides
    """Hip pitch joints' actuator indices (into ``joint_pos`` and ``motor_pos``)."""
    waist_roll: int
    """The waist roll joint's actuator index."""


def leg_joints(robot: Robot) -> LegJoints:
    """Find the leg vector's actuators and the controller's named joints in ``robot``.

    Raises:
        UnknownNameError: a joint the controller needs (``l_hip_pitch``, ..., ``waist_roll``)
            is not one of the robot's actuated joints; the message lists them.
        LegChainError: a leg is not the six-joint chain the IK solves.
    """
    names = list(robot.joint_names)
    per_leg = [
        sorted(names.index(n) for n in LegGeometry.from_robot(robot, side).names) for side in SIDES
    ]
    vector = [a for leg in per_leg for a in leg]
    start, size = len(per_leg[LEFT]), len(vector)
    legs = (tuple(range(start)), tuple(range(start, size)))

    def actuator(name: str) -> int:
        if name not in names:
            raise UnknownNameError("joint", name, robot.joint_names)
        return names.index(name)

    def position(joint: str) -> Sides:
        found = []
        for side, leg in zip(SIDES, legs, strict=True):
            name = f"{side}_{joint}"
            at = actuator(name)
            if at not in vector or vector.index(at) not in leg:
                raise UnknownNameError(f"{side} leg joint", name, [names[vector[i]] for i in leg])
            found.append(vector.index(at))
        return Sides(*found)

    hip, knee, ankle = position(HIP_PITCH), position(KNEE), position(ANKLE_PITCH)
    index = np.array(vector, dtype=np.int64)
    contiguous = np.array_equal(index, np.arange(index.min(), index.min() + size))
    return LegJoints(
        actuators=slice(int(index.min()), int(index.min()) + size) if contiguous else index,
        actuator_list=tuple(vector),
        legs=legs,
        leg_of=tuple(LEFT if i in legs[LEFT] else RIGHT for i in range(size)),
        hip_pitch=hip,
        knee=knee,
        ankle_pitch=ankle,
        sagittal=(
            (hip.left, knee.left, ankle.left),
            (hip.right, knee.right, ankle.right),
        ),
        hip_pitch_actuator=Sides(vector[hip.left], vector[hip.right]),
        waist_roll=actuator(WAIST_ROLL),
    )
