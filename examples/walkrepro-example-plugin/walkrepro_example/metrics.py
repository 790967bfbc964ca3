"""A metric measured from the log: how far the pelvis sinks below its start."""

from __future__ import annotations

import numpy as np

from walkrepro.evaluation.metrics import LogData, metric


@metric("pelvis_sag", "largest drop of the pelvis height below its start, before a fall [m]")
def pelvis_sag(d: LogData, arg: str) -> float:
    d.require_states()  # NotMeasurable (NaN with a reason) for a log without states
    z = d.qpos[:, 2]  # the free joint's height, world frame [m]
    return float(z[0] - np.min(z))
