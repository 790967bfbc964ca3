"""The spring of a series-elastic joint, with or without a dead band (backlash).

A series-elastic joint ``j`` is a motor DoF ``j_motor`` and a spring DoF ``j`` on one axis
(walkrepro/sim/robot.py); the spring DoF's angle q_s is link − motor. Its spring is either
the spring DoF's own ``stiffness`` (a linear spring, τ = −K q_s), or, where the drive has a
backlash, a fixed tendon ``j_spring`` on that DoF (coefficient 1) with stiffness K and
spring length [−b/2, b/2]: MuJoCo's dead-band tendon spring (``springlength`` with two
values), whose passive torque is

    τ = −K (q_s − b/2)   for q_s > b/2,
    τ = 0                for |q_s| ≤ b/2,
    τ = −K (q_s + b/2)   for q_s < −b/2       [Nm],

a gap of width b [rad] in series with the spring K [Nm/rad] (Paper II, Hardware Control:
"significant backlashes in the knee and ankle joints"; the massless node between gap and
spring eliminated). The tendon acts on the spring DoF only, i.e. on the relative angle, so
its torque acts equally and oppositely on the motor and on the link.
"""

from __future__ import annotations

import fnmatch

import mujoco

#: Suffix of the fixed tendon that is a spring DoF's spring when its drive has a backlash.
SPRING_TENDON_SUFFIX = "_spring"


def spring_tendon(model: mujoco.MjModel, joint: str) -> int:
    """The id of joint ``joint``'s dead-band spring tendon, or −1 if its spring is linear."""
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, joint + SPRING_TENDON_SUFFIX)


def spring_law(model: mujoco.MjModel, joint: str) -> tuple[float, float]:
    """(K [Nm/rad], b [rad]) of the spring of series-elastic joint ``joint``.

    Its dead-band tendon's stiffness and band width if it has one, else the spring DoF's own
    stiffness and b = 0.
    """
    tendon = spring_tendon(model, joint)
    if tendon < 0:
        return float(model.jnt_stiffness[model.joint(joint).id]), 0.0
    low, high = model.tendon_lengthspring[tendon]
    return float(model.tendon_stiffness[tendon]), float(high - low)


def preload_deflection(torque: float, stiffness: float, backlash: float) -> float:
    """The spring DoF angle q_s [rad] at which the spring holds ``torque`` [Nm] at rest.

    The inverse of the dead-band law above for τ ≠ 0: q_s = −τ/K − sign(τ) b/2 (the load
    closes the half band on its side); 0 for τ = 0 (the middle of the band).
    """
    sign = float(torque > 0) - float(torque < 0)
    return -torque / stiffness - sign * backlash / 2


def series_elastic_joints(model: mujoco.MjModel, banded: bool = False) -> list[str]:
    """Names of the series-elastic joints (a spring DoF ``j`` whose actuator drives
    ``j_motor``), in actuator order; with ``banded`` only those with a dead-band tendon."""
    names = []
    for i in range(model.nu):
        name = model.actuator(i).name
        target = int(model.actuator_trnid[i, 0])
        motor = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, target) or ""
        if (
            motor != name + "_motor"
            or mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) < 0
        ):
            continue
        if not banded or spring_tendon(model, name) >= 0:
            names.append(name)
    return names


def set_springs(
    mjspec: mujoco.MjSpec, spring: dict[str, float], backlash: dict[str, float]
) -> None:
    """Set K [Nm/rad] and dead band b [rad] of the series-elastic joints matching the globs
    (a spec's ``actuators.spring`` / ``actuators.backlash``; later globs win).

    K goes to the joint's dead-band tendon if it has one, else to the spring DoF's
    stiffness; b to the tendon's spring length [−b/2, b/2]. The spec loader has checked
    that every glob matches a joint that can take it.
    """
    tendons = {t.name: t for t in mjspec.tendons}
    names = [a.name for a in mjspec.actuators if a.target == a.name + "_motor"]
    for pattern, k in spring.items():
        for name in fnmatch.filter(names, pattern):
            tendon = tendons.get(name + SPRING_TENDON_SUFFIX)
            element = tendon if tendon is not None else mjspec.joint(name)
            # MjSpec's stiffness is (linear, higher-order terms); the spring is linear.
            element.stiffness = [k, 0.0, 0.0]
    for pattern, b in backlash.items():
        for name in fnmatch.filter(names, pattern):
            tendons[name + SPRING_TENDON_SUFFIX].springlength = [-b / 2, b / 2]
