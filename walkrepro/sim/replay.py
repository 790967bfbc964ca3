"""Re-simulate a log from its own scene, initial state and per-step inputs.

This is what ``walkrepro verify <log>`` runs. It proves that a log is complete: the MJCF
(``scene.xml``), the state before step 0 and the inputs of every physics step (``ctrl`` and
``xfrc_applied``) reproduce every logged state. MuJoCo is deterministic on one machine and
build, so a faithful log replays with deviation exactly 0. A truncated or damaged log
replays as far as it can be read and never verifies: the report says what is wrong, and how
many of the steps the file held were replayed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np

from walkrepro.errors import UnknownNameError, WalkreproError
from walkrepro.log.record import TOPIC_INPUTS, TOPIC_STATE, Log, read_log
from walkrepro.sim import contact_law

#: Default tolerance on the max abs state deviation, in the units of qpos/qvel/act.
DEFAULT_TOLERANCE = 1e-9
_STATE_FIELDS = ("qpos", "qvel", "act")


@dataclass(frozen=True)
class VerifyReport:
    """The outcome of re-simulating a log.

    Attributes:
        n_steps: physics steps replayed (= ``/sim/inputs`` messages).
        n_states_compared: logged states after step 0 compared with the replay.
        max_deviation: largest |replayed - logged| over qpos, qvel and act.
        worst_step: step index of the state with ``max_deviation`` (-1 if none compared).
        worst_field: entry with ``max_deviation``, e.g. ``"qvel[3]"`` (``""`` if none).
        ok: the log is whole, at least one state was compared and
            ``max_deviation <= tolerance``.
        tolerance: the tolerance used.
        n_logged: physics steps the log says it holds (``/sim/inputs`` messages in its
            summary); None when the summary is gone (a truncated file).
        damage: why the log is not whole, one sentence (``""`` when it is), see
            :attr:`walkrepro.log.record.Log.damage`.
        n_states_read: ``/sim/state`` messages that could be read.
        last_time: time of the last state that could be read [s] (NaN if none).
    """

    n_steps: int
    n_states_compared: int
    max_deviation: float
    worst_step: int
    worst_field: str
    ok: bool
    tolerance: float
    n_logged: int | None = None
    damage: str = ""
    n_states_read: int = 0
    last_time: float = math.nan


class ReplayInputs(NamedTuple):
    """A log's per-step inputs, ready to apply.

    Attributes:
        ctrl: ``MjData.ctrl`` of each physics step, shape (n_steps, nu).
        xfrc: for each step, the whole ``MjData.xfrc_applied`` (nbody, 6) to set, or None
            where it is unchanged from the previous step (zero before the first).
    """

    ctrl: np.ndarray
    xfrc: list[np.ndarray | None]


def replay_inputs(log: Log, model: mujoco.MjModel) -> ReplayInputs:
    """The ``/sim/inputs`` of ``log`` for ``model``, checked: steps 0..N-1 once each, vector
    sizes and body names that fit the scene.

    Raises:
        WalkreproError: gaps or duplicates in the steps, or vectors that do not fit.
    """
    path = log.path
    inputs = sorted(log.messages(TOPIC_INPUTS), key=lambda message: message["step"])
    steps = [int(message["step"]) for message in inputs]
    if steps != list(range(len(steps))):
        missing = sorted(set(range(max(steps) + 1)) - set(steps))
        raise WalkreproError(
            f"{path}: {TOPIC_INPUTS} must hold steps 0..N-1 once each; "
            f"missing steps {_ranges(missing) or 'none'}"
            + (", with duplicates" if len(set(steps)) != len(steps) else "")
        )
    body_ids = {
        name: i
        for i in range(model.nbody)
        if (name := mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i))
    }
    ctrl = np.zeros((len(inputs), model.nu))
    xfrc: list[np.ndarray | None] = []
    pushed = False  # whether the previous step applied any wrench
    for message in inputs:
        step = message["step"]
        target = ctrl[step]
        _assign(target, message["ctrl"], f"{TOPIC_INPUTS} step {step} ctrl", path)
        if not message["xfrc"] and not pushed:
            xfrc.append(None)
            continue
        applied = np.zeros((model.nbody, 6))
        for body, wrench in message["xfrc"].items():
            body_id = body_ids.get(body)
            if body_id is None:
                raise UnknownNameError("body", body, body_ids, f"{path}: step {step} xfrc")
            _assign(applied[body_id], wrench, f"{TOPIC_INPUTS} step {step} xfrc {body}", path)
        xfrc.append(applied)
        pushed = bool(message["xfrc"])
    return ReplayInputs(ctrl, xfrc)


class LoggedStates(NamedTuple):
    """A log's ``/sim/state`` messages as arrays (see :meth:`Log.arrays`).

    Attributes:
        rows: step -> row of the arrays.
        t: time of each state [s], shape (N,).
        fields: ``qpos``, ``qvel``, ``act`` -> shape (N, n).
    """

    rows: dict[int, int]
    t: np.ndarray
    fields: dict[str, np.ndarray]


def logged_states(log: Log) -> LoggedStates:
    """The log's states, by step.

    Raises:
        WalkreproError: the states are not numbers and fixed-size vectors.
    """
    try:
        arrays = log.arrays(TOPIC_STATE)
    except ValueError as exc:
        raise WalkreproError(f"{log.path}: {TOPIC_STATE}: {exc}") from None
    if not arrays:
        return LoggedStates({}, np.zeros(0), {})
    rows = {int(step): i for i, step in enumerate(arrays["step"])}
    return LoggedStates(rows, arrays["t"], {name: arrays[name] for name in _STATE_FIELDS})


def set_initial_state(log: Log, data: mujoco.MjData) -> LoggedStates:
    """Sets ``data`` to the log's step-0 state (time, qpos, qvel, act); returns every logged
    state (:func:`logged_states`).

    Raises:
        WalkreproError: no step-0 state, or vectors that do not fit the scene.
    """
    states = logged_states(log)
    row = states.rows.get(0)
    if row is None:
        raise WalkreproError(f"{log.path}: no {TOPIC_STATE} message with step 0; cannot replay")
    data.time = float(states.t[row])
    for name in _STATE_FIELDS:
        values = states.fields[name][row]
        _assign(getattr(data, name), values, f"{TOPIC_STATE} step 0 {name}", log.path)
    return states


def verify_log(path: Path, tolerance: float = DEFAULT_TOLERANCE) -> VerifyReport:
    """Re-simulates the log at ``path`` and compares every logged state.

    Starting from the step-0 ``/sim/state`` (time, qpos, qvel, act), each ``/sim/inputs``
    message k sets ``ctrl`` and ``xfrc_applied`` (zero for unlisted bodies) and takes one
    ``mj_step``; the result is compared with the logged state of step k + 1, if any.

    Args:
        path: the MCAP log (a truncated or damaged log replays as far as it can be read,
            and is reported as such).
        tolerance: largest acceptable max abs deviation.

    Returns:
        The report; ``ok`` says whether the log is whole and reproduces itself.

    Raises:
        WalkreproError: unreadable log, no step-0 state in a whole log, gaps in the
            inputs, or vectors that do not fit the logged scene.
    """
    log = read_log(path, check_indexes=True)
    model = mujoco.MjModel.from_xml_string(log.scene_xml)
    data = mujoco.MjData(model)
    inputs = replay_inputs(log, model)
    read = logged_states(log)
    n_logged = log.logged_count(TOPIC_INPUTS)
    last_time = float(read.t[-1]) if read.t.size else math.nan
    if log.damage and 0 not in read.rows:  # cut or damaged before the first state
        return VerifyReport(
            0, 0, 0.0, -1, "", False, tolerance, n_logged, log.damage, len(read.rows), last_time
        )
    states = set_initial_state(log, data)

    max_deviation = 0.0
    worst_step = -1
    worst_field = ""
    n_compared = 0
    # The scene's own ground law, if it carries one (walkrepro/sim/contact_law.py), acts in the
    # replayed steps as it did in the run's.
    with contact_law.applied_to(model):
        for step, (ctrl, xfrc) in enumerate(zip(inputs.ctrl, inputs.xfrc, strict=True)):
            data.ctrl[:] = ctrl
            if xfrc is not None:
                data.xfrc_applied[:] = xfrc
            mujoco.mj_step(model, data)
            row = states.rows.get(step + 1)
            if row is None:
                continue
            n_compared += 1
            for name in _STATE_FIELDS:
                replayed = getattr(data, name)
                expected = states.fields[name][row]
                if expected.shape != replayed.shape:
                    raise WalkreproError(
                        f"{path}: {TOPIC_STATE} step {step + 1} {name} has {expected.size} "
                        f"entries, the scene has {replayed.size}"
                    )
                if expected.size == 0:
                    continue
                error = np.abs(replayed - expected)
                i = int(np.argmax(error))  # the first NaN, if any
                # A diverged (NaN) replay counts as infinitely far, never as "no deviation".
                deviation = math.inf if math.isnan(error[i]) else float(error[i])
                if deviation > max_deviation or worst_step == -1:
                    max_deviation = deviation
                    worst_step = step + 1
                    worst_field = f"{name}[{i}]"

    return VerifyReport(
        n_steps=len(inputs.ctrl),
        n_states_compared=n_compared,
        max_deviation=max_deviation,
        worst_step=worst_step,
        worst_field=worst_field,
        ok=not log.damage and n_compared > 0 and max_deviation <= tolerance,
        tolerance=tolerance,
        n_logged=n_logged,
        damage=log.damage,
        n_states_read=len(read.rows),
        last_time=last_time,
    )


def _assign(target: np.ndarray, values: Any, what: str, path: Path) -> None:
    """``target[:] = values`` with a size check that names the offending message."""
    values = np.asarray(values, dtype=float)
    if values.shape != target.shape:
        raise WalkreproError(
            f"{path}: {what} has {values.size} entries, the scene has {target.size}"
        )
    target[:] = values


def _ranges(steps: list[int]) -> str:
    """``[3, 4, 5, 9]`` -> ``"3-5, 9"``, so a long gap prints as one range."""
    parts: list[tuple[int, int]] = []
    for step in steps:
        if parts and parts[-1][1] == step - 1:
            parts[-1] = (parts[-1][0], step)
        else:
            parts.append((step, step))
    return ", ".join(str(a) if a == b else f"{a}-{b}" for a, b in parts)
