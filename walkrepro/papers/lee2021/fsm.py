"""The states of the event-based finite-state machine of Lee et al. 2021, §III and Table I.

The E-FSM itself runs compiled, :func:`.kernels.fsm_step`. Its readable numpy reference (the
laws L1–L3, the capture point of Eq. (2), ε and the transitions of Table I) is a test oracle,
``tests/oracles/efsm_fsm.py``, which ``tests/test_efsm_kernels.py`` compares with the kernel
tick by tick.
"""

from __future__ import annotations

from enum import IntEnum


class Phase(IntEnum):
    """E-FSM states (Table I)."""

    SSD = 0  #: single support, decelerate the CoM
    SSA = 1  #: single support, accelerate the CoM toward the swing foot
    DS = 2  #: double support, move the desired CoP to the swing foot
