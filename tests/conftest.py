"""Shared test fixtures."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from walkrepro.runtime import numbacache

# Importing walkrepro sets up nothing; the tests compile kernels as the command does, in the
# source-keyed cache (an edit to a helper a kernel inlines recompiles it), and the commands
# they start in child processes inherit it. Before anything below compiles a kernel.
numbacache.install()

from walkrepro.sim.robot import load_robot  # noqa: E402
from walkrepro.sim.sensors import SensorSnapshot  # noqa: E402


def _kist_home_snapshot() -> SensorSnapshot:
    """kist_humanoid standing still at home: exact encoders and base state, each foot's F/T
    carrying half its weight."""
    robot = load_robot("kist_humanoid")
    q = robot.home_qpos
    return SensorSnapshot(
        t=0.0,
        joint_pos=robot.home_joint_pos.copy(),
        joint_vel=np.zeros(robot.n_joints),
        imu_quat=np.array([1.0, 0, 0, 0]),
        imu_gyro=np.zeros(3),
        imu_acc=np.array([0, 0, 9.81]),
        left_ft=np.array([0, 0, 280.0, 0, 0, 0]),
        right_ft=np.array([0, 0, 280.0, 0, 0, 0]),
        base_pos=q[0:3].copy(),
        base_quat=q[3:7].copy(),
        base_linvel=np.zeros(3),
        base_angvel=np.zeros(3),
    )


@pytest.fixture
def kist_home_snapshot() -> Callable[[], SensorSnapshot]:
    """Makes a fresh kist_humanoid home snapshot per call (controllers may keep references)."""
    return _kist_home_snapshot


@pytest.fixture(autouse=True)
def _clean_tree_for_tests(monkeypatch: pytest.MonkeyPatch) -> None:
    """Commands that refuse to write references from uncommitted changes see a clean tree:
    a test's outcome must not depend on the developer's uncommitted edits
    (tests/test_ledger.py checks the refusal itself)."""
    from walkrepro.runs import provenance

    monkeypatch.setattr(provenance, "dirty_paths", lambda folders: [])
