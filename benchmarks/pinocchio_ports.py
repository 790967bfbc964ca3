"""Why the whole-body ticks compute some of Pinocchio's quantities themselves.

The compiled ticks of Paper I (``lee2021/kernels.py``) and Paper III (``jo_oh/tasks.py``)
compute a few of Pinocchio's quantities inside the kernel instead of calling Pinocchio:
frame Jacobians, frame classical accelerations, frame placements, A⁻¹, log₃ and roll-pitch-yaw.
Each such call from Python crosses the Python/C++ boundary and returns a new numpy array;
inside the kernel the same arithmetic costs a few tens of nanoseconds. This script measures
both, per call, on the robots of the two papers, and multiplies by the calls a tick makes:
the difference is what calling Pinocchio would add to every control tick.

Run: ``python benchmarks/pinocchio_ports.py`` (about 20 s). Absolute times drift with the
machine's load; compare the columns of one run.
"""

from __future__ import annotations

import timeit

import numba
import numpy as np
import pinocchio as pin

from walkrepro.papers.jo_oh.tasks import matrix_to_rpy
from walkrepro.papers.lee2021 import kernels
from walkrepro.sim.robot import frame_classical_acceleration, frame_jacobian, load_robot, log3

#: Calls per control tick: (Paper I's tick in double support, Paper III's tick); Paper I's
#: tick places four frames, one updateFramePlacements would do them all.
CALLS_PER_TICK = {
    "frame Jacobian (getFrameJacobian)": (2, 4),
    "frame classical acceleration (getFrameClassicalAcceleration)": (2, 2),
    "frame placement (updateFramePlacements)": (1, 0),
    "A⁻¹ (computeMinverse; kernel: inv of A)": (1, 0),
    "log₃ (log3)": (2, 2),
    "roll-pitch-yaw (rpy.matrixToRpy)": (0, 2),
}
REPEAT = 2000


@numba.njit(cache=False)
def _loop_jacobian(
    j: np.ndarray, chain: np.ndarray, p: np.ndarray, out: np.ndarray, n: int
) -> None:
    for _ in range(n):
        frame_jacobian(j, chain, p, out)


@numba.njit(cache=False)
def _loop_acceleration(
    rot: np.ndarray, vel: np.ndarray, acc: np.ndarray, offset: np.ndarray, out: np.ndarray, n: int
) -> None:
    for _ in range(n):
        frame_classical_acceleration(rot, vel, acc, offset, out)


@numba.njit(cache=False)
def _loop_minv(mass: np.ndarray, n: int) -> None:
    for _ in range(n):
        np.linalg.inv(kernels.symmetric_from_upper(mass))


@numba.njit(cache=False)
def _loop_log3(rot: np.ndarray, out: np.ndarray, n: int) -> None:
    for _ in range(n):
        log3(rot, out)


@numba.njit(cache=False)
def _loop_rpy(rot: np.ndarray, out: np.ndarray, n: int) -> None:
    for _ in range(n):
        matrix_to_rpy(rot, out)


@numba.njit(cache=False)
def _loop_placement(
    jr: np.ndarray,
    jp: np.ndarray,
    lr: np.ndarray,
    lp: np.ndarray,
    r: np.ndarray,
    p: np.ndarray,
    n: int,
) -> None:
    for _ in range(n):
        r[:], p[:] = kernels.frame_placement(jr, jp, lr, lp)


def _per_call(fn, number: int = REPEAT) -> float:
    """Fastest of five timings, µs per call."""
    fn()
    return min(timeit.repeat(fn, number=number, repeat=5)) / number * 1e6


def measure(robot_name: str) -> dict[str, tuple[float, float]]:
    """{quantity: (Pinocchio from Python [µs], the kernel's own inside a kernel [µs])}."""
    robot = load_robot(robot_name)
    model = robot.pin_model
    data = model.createData()
    rng = np.random.default_rng(0)
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    q[3:7] /= np.linalg.norm(q[3:7])
    v = rng.standard_normal(model.nv)
    pin.computeAllTerms(model, data, q, v)
    pin.updateFramePlacements(model, data)
    fid = (
        model.getFrameId("left_foot_sole")
        if model.existFrame("left_foot_sole")
        else model.nframes - 1
    )
    frame = model.frames[fid]
    jid = frame.parentJoint
    lwa = pin.LOCAL_WORLD_ALIGNED
    chain = np.zeros(model.nv, dtype=np.bool_)
    chain[[i for i in range(model.nv) if data.J[:, i].any()]] = True
    jac, acc6 = np.empty((6, model.nv)), np.empty(6)
    rot_j, pos_j = data.oMi[jid].rotation.copy(), data.oMi[jid].translation.copy()
    vel_j, acc_j = data.v[jid].vector.copy(), data.a[jid].vector.copy()
    local_r, local_p = frame.placement.rotation.copy(), frame.placement.translation.copy()
    mass = data.M.copy()
    r3, p3, out3 = np.empty((3, 3)), np.empty(3), np.empty(3)
    position = data.oMf[fid].translation.copy()
    n = REPEAT
    return {
        "frame Jacobian (getFrameJacobian)": (
            _per_call(lambda: pin.getFrameJacobian(model, data, fid, lwa)),
            _per_call(lambda: _loop_jacobian(data.J, chain, position, jac, n), 1) / n,
        ),
        "frame classical acceleration (getFrameClassicalAcceleration)": (
            _per_call(lambda: pin.getFrameClassicalAcceleration(model, data, fid, lwa).vector),
            _per_call(lambda: _loop_acceleration(rot_j, vel_j, acc_j, local_p, acc6, n), 1) / n,
        ),
        "frame placement (updateFramePlacements)": (
            _per_call(lambda: pin.updateFramePlacements(model, data)),
            _per_call(lambda: _loop_placement(rot_j, pos_j, local_r, local_p, r3, p3, n), 1) / n,
        ),
        "A⁻¹ (computeMinverse; kernel: inv of A)": (
            _per_call(lambda: pin.computeMinverse(model, data, q)),
            _per_call(lambda: _loop_minv(mass, n), 1) / n,
        ),
        "log₃ (log3)": (
            _per_call(lambda: pin.log3(rot_j)),
            _per_call(lambda: _loop_log3(rot_j, out3, n), 1) / n,
        ),
        "roll-pitch-yaw (rpy.matrixToRpy)": (
            _per_call(lambda: pin.rpy.matrixToRpy(rot_j)),
            _per_call(lambda: _loop_rpy(rot_j, out3, n), 1) / n,
        ),
    }


def main() -> None:
    for paper, robot_name in enumerate(("dyros_red", "kist_humanoid")):
        rows = measure(robot_name)
        label = ("Paper I", "Paper III")[paper]
        print(f"\n{label} ({robot_name}), µs per call and per tick")
        print(f"{'quantity':64s} {'Pinocchio':>9s} {'kernel':>7s} {'calls':>5s} {'Δ/tick':>7s}")
        total = 0.0
        for name, (py, jit) in rows.items():
            calls = CALLS_PER_TICK[name][paper]
            total += calls * (py - jit)
            print(f"{name:64s} {py:9.2f} {jit:7.3f} {calls:5d} {calls * (py - jit):7.2f}")
        print(
            f"{'calling Pinocchio instead would add per tick':64s} {'':9s} {'':7s} {'':5s} {total:7.2f}"
        )


if __name__ == "__main__":
    main()
