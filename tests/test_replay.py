"""Tests of walkrepro.sim.replay: re-simulating a log reproduces it, and tampering is caught."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from walkrepro.cli import app
from walkrepro.errors import WalkreproError
from walkrepro.log.record import (
    TOPIC_EVENTS,
    TOPIC_INPUTS,
    TOPIC_STATE,
    LogWriter,
    read_log,
)
from walkrepro.sim.replay import verify_log

# A free box that lands on the floor (contacts) and a 2-link pendulum driven by a motor and
# a first-order filter actuator (so `act` is non-empty).
SCENE_XML = """
<mujoco model="tiny">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <body name="box" pos="0.8 0 0.2">
      <freejoint/>
      <geom type="box" size="0.05 0.05 0.05" mass="1"/>
    </body>
    <body name="link1" pos="0 0 1">
      <joint name="hinge1" type="hinge" axis="0 1 0" damping="0.01"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
      <body name="link2" pos="0 0 -0.3">
        <joint name="hinge2" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor name="m1" joint="hinge1"/>
    <general name="m2" joint="hinge2" dyntype="filter" dynprm="0.02" gainprm="1"/>
  </actuator>
</mujoco>
"""
STEPS = 300
PUSH_STEPS = range(100, 140)
PUSH = [0.0, 20.0, 0.0, 0.0, 0.0, 0.3]  # [N] and [N m] on the box, world frame
METADATA = {"git_commit": "abc1234", "seed": "0", "experiment": "tiny"}


def simulate(
    path: Path,
    *,
    state_every: int = 1,
    log_inputs: Callable[[int, dict], dict | None] = lambda step, msg: msg,
    skip_state0: bool = False,
    chunk_size: int = 1 << 20,
) -> None:
    """Simulates the tiny scene and logs it per the contract.

    ``log_inputs(step, message)`` may alter the *logged* inputs (or return None to drop them)
    without changing what was simulated.
    """
    model = mujoco.MjModel.from_xml_string(SCENE_XML)
    data = mujoco.MjData(model)
    box = model.body("box").id
    with LogWriter(
        path, scene_xml=SCENE_XML, spec_yaml="name: tiny\n", metadata=METADATA,
        chunk_size=chunk_size,
    ) as log:  # fmt: skip
        for step in range(STEPS):
            if step % state_every == 0 and not (skip_state0 and step == 0):
                state = {"step": step, "t": data.time, "qpos": data.qpos, "qvel": data.qvel,
                         "act": data.act}  # fmt: skip
                log.write(TOPIC_STATE, state, data.time)
            data.ctrl[:] = [0.5 * np.sin(20 * data.time), 0.3 * np.cos(15 * data.time)]
            data.xfrc_applied[:] = 0.0
            xfrc = {}
            if step in PUSH_STEPS:
                data.xfrc_applied[box] = PUSH
                xfrc["box"] = list(PUSH)
            logged = log_inputs(step, {"step": step, "ctrl": data.ctrl.tolist(), "xfrc": xfrc})
            if logged is not None:
                log.write(TOPIC_INPUTS, logged, data.time)
            if step == PUSH_STEPS[0]:
                log.write(TOPIC_EVENTS, {"t": data.time, "kind": "push", "body": "box"}, data.time)
            mujoco.mj_step(model, data)
        log.write(
            TOPIC_STATE,
            {"step": STEPS, "t": data.time, "qpos": data.qpos, "qvel": data.qvel,
             "act": data.act},
            data.time,
        )  # fmt: skip
        log.close("complete")


def test_faithful_log_replays_exactly(tmp_path: Path) -> None:
    """Re-simulating an untampered log reproduces every logged state with zero deviation."""
    path = tmp_path / "run.mcap"
    simulate(path)
    report = verify_log(path)
    assert report.ok
    assert report.n_steps == STEPS
    assert report.n_states_compared == STEPS
    assert report.max_deviation <= 1e-9
    assert report.tolerance == 1e-9


def test_scene_actually_moves(tmp_path: Path) -> None:
    """The scene moves (box falls and is pushed, pendulum swings, act evolves): 0 is no fluke."""
    path = tmp_path / "run.mcap"
    simulate(path)
    states = read_log(path).messages(TOPIC_STATE)
    first, last = np.array(states[0]["qpos"]), np.array(states[-1]["qpos"])
    moved = np.abs(last - first)
    assert moved[1] > 1e-2  # box pushed along y [m]
    assert moved[2] > 1e-2  # box fell [m]
    assert moved[7] > 1e-2 and moved[8] > 1e-2  # both hinges swung [rad]
    assert abs(states[-1]["act"][0]) > 1e-3


def test_sparse_states_still_verify(tmp_path: Path) -> None:
    """States logged only every 4th step (control ticks) are compared where present."""
    path = tmp_path / "run.mcap"
    simulate(path, state_every=4)
    report = verify_log(path)
    assert report.ok
    assert report.n_steps == STEPS
    assert report.n_states_compared == STEPS // 4


def test_tampered_ctrl_fails(tmp_path: Path) -> None:
    """Changing one logged ctrl value makes the replay deviate from the logged states."""
    path = tmp_path / "tampered.mcap"

    def tamper(step: int, message: dict) -> dict:
        if step == 150:
            message["ctrl"][0] += 1e-3
        return message

    simulate(path, log_inputs=tamper)
    report = verify_log(path)
    assert not report.ok
    assert report.max_deviation > 1e-9
    assert report.worst_step > 150
    assert report.worst_field.startswith(("qpos[", "qvel["))


def test_xfrc_is_replayed(tmp_path: Path) -> None:
    """The logged push is applied on replay: with it the log verifies, without it it does not."""
    pushed = tmp_path / "pushed.mcap"
    simulate(pushed)
    assert verify_log(pushed).ok

    def drop_push(step: int, message: dict) -> dict:
        message["xfrc"] = {}
        return message

    unpushed = tmp_path / "push_not_logged.mcap"
    simulate(unpushed, log_inputs=drop_push)
    report = verify_log(unpushed)
    assert not report.ok
    assert report.worst_step > PUSH_STEPS[0]


def test_truncated_log_replays_its_prefix_and_fails(tmp_path: Path) -> None:
    """A log cut mid-file (writer killed) replays as far as it goes, faithfully, but does not verify: the report says it is truncated and the number of logged steps is unknown."""
    path = tmp_path / "run.mcap"
    simulate(path, chunk_size=8 << 10)
    whole = verify_log(path)
    assert whole.ok and whole.damage == "" and whole.n_logged == whole.n_steps == STEPS
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    report = verify_log(path)
    assert not report.ok and report.damage.startswith("truncated")
    assert report.max_deviation == 0.0 and 0 < report.n_states_compared < STEPS
    assert report.n_logged is None and 0 < report.n_steps < STEPS


def test_missing_initial_state_is_an_error(tmp_path: Path) -> None:
    """A log without the step-0 state cannot be replayed and says so."""
    path = tmp_path / "run.mcap"
    simulate(path, skip_state0=True)
    with pytest.raises(WalkreproError, match="step 0"):
        verify_log(path)


def test_gap_in_inputs_is_an_error(tmp_path: Path) -> None:
    """Missing inputs for some steps make verification fail with the missing step range."""
    path = tmp_path / "run.mcap"
    simulate(path, log_inputs=lambda step, msg: None if 40 <= step < 43 else msg)
    with pytest.raises(WalkreproError, match="40-42"):
        verify_log(path)


# --- verify on a real run's log, cut or with flipped bytes ------------------------------


@pytest.fixture(scope="module")
def short_run_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The log of a 0.5 s stand_coman run (1000 physics steps, several chunks), made once."""
    out = tmp_path_factory.mktemp("runs")
    result = CliRunner().invoke(
        app,
        ["run", "stand_coman", "--set", "sim.duration=0.5", "--out", str(out), "--no-figures"],
    )
    assert result.exit_code == 0, result.output
    (log,) = out.glob("stand_coman/*/log.mcap")
    return log


def _verify(path: Path) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["verify", str(path)])
    return result.exit_code, " ".join(result.output.split())  # unwrap the console's lines


def test_whole_log_verifies_all_its_steps(short_run_log: Path) -> None:
    """The whole log verifies: exit 0, every logged step replayed."""
    code, text = _verify(short_run_log)
    assert code == 0 and text.startswith("OK: replayed 1000 of 1000 logged steps"), text


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.9])
def test_cut_log_is_reported_truncated(
    short_run_log: Path, tmp_path: Path, fraction: float
) -> None:
    """A log cut at 10, 50 or 90 % exits 1, says it is truncated, what was read, and that N of an unknown number of steps were replayed."""
    data = short_run_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    code, text = _verify(cut)
    assert code == 1, text
    assert text.startswith("DAMAGED:") and "is truncated: it ends at byte" in text, text
    report = verify_log(cut)
    assert not report.ok and report.n_logged is None
    assert f"replayed {report.n_steps} of ? logged steps" in text, text
    assert f"Read {report.n_states_read} states" in text and "unknown" in text
    assert report.n_steps < 1000 and report.max_deviation == 0.0
    if fraction > 0.1:  # past the first chunk: a prefix was read and replays faithfully
        assert report.n_steps > 0 and report.n_states_compared > 0


def test_cut_in_the_attachments_is_an_error_that_says_truncated(
    short_run_log: Path, tmp_path: Path
) -> None:
    """A log cut before its scene attachment ends is a one-paragraph error (exit 2) that says it is truncated."""
    data = short_run_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:1000])
    code, text = _verify(cut)
    assert code == 2 and "is truncated" in text and "attachment" in text, text
    assert "Traceback" not in text


@pytest.mark.parametrize("where", ["middle", "summary"])
def test_flipped_bytes_are_reported_damaged(
    short_run_log: Path, tmp_path: Path, where: str
) -> None:
    """Bytes flipped mid-file (in a chunk) or in the summary: exit 1, says damaged, and gives the logged step count when the summary survives."""
    data = bytearray(short_run_log.read_bytes())
    at = len(data) // 2 if where == "middle" else len(data) - 100
    for i in range(at, at + 4):
        data[i] ^= 0xFF
    damaged = tmp_path / "flipped.mcap"
    damaged.write_bytes(bytes(data))
    code, text = _verify(damaged)
    assert code == 1, text
    assert text.startswith("DAMAGED:") and "is damaged" in text, text
    report = verify_log(damaged)
    assert not report.ok and report.max_deviation == 0.0
    if where == "middle":  # the summary still counts the steps; those after the damage are lost
        assert report.n_logged == 1000 and 0 < report.n_steps < 1000
        assert f"replayed {report.n_steps} of 1000 logged steps" in text, text
    else:  # every chunk is whole; the summary that counts them is not
        assert report.n_logged is None and report.n_steps == 1000
        assert "replayed 1000 of ? logged steps" in text, text


def _records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, length of the body) of each top-level record of an MCAP file."""
    out, pos = [], 8  # after the opening magic
    while pos < len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, opcode, length))
        pos += 9 + length
    return out


@pytest.mark.parametrize(
    ("opcode", "code", "words"),
    [
        (0x09, 2, "is damaged at byte"),  # an attachment: its CRC fails
        (0x03, 1, "differ from the copies in its summary"),  # a schema
        (0x07, 1, "is damaged at byte"),  # a message index: not what its chunk holds
    ],
    ids=["attachment", "schema", "message index"],
)
def test_a_flipped_byte_in_records_without_chunk_checksums_is_found(
    short_run_log: Path, tmp_path: Path, opcode: int, code: int, words: str
) -> None:
    """A byte flipped in an attachment, a schema or a message index (records outside the chunks' checksums) is reported as damage, never OK."""
    data = bytearray(short_run_log.read_bytes())
    offset, _, length = next(r for r in _records(bytes(data)) if r[1] == opcode)
    data[offset + 9 + length // 2] ^= 0x10  # the middle of the record's body
    damaged = tmp_path / "flipped.mcap"
    damaged.write_bytes(bytes(data))
    got, text = _verify(damaged)
    assert got == code and words in text and "Traceback" not in text, text
    if opcode == 0x03:  # decoded with the summary's copy: everything replays, still not OK
        assert text.startswith("DAMAGED:") and "replayed 1000 of 1000 logged steps" in text


def test_a_log_from_the_mcap_library_writer_verifies(tmp_path: Path) -> None:
    """A log written by the mcap library's own writer (its message indexes and summary, format 1 JSON topics) verifies OK: the damage checks accept any valid MCAP."""
    import json

    from mcap.writer import Writer

    from walkrepro.log.record import METADATA_NAME, SCENE_ATTACHMENT, SPEC_ATTACHMENT

    model = mujoco.MjModel.from_xml_string(SCENE_XML)
    data = mujoco.MjData(model)
    path = tmp_path / "format1.mcap"
    with path.open("wb") as f:
        writer = Writer(f, chunk_size=4 << 10)
        writer.start()
        writer.add_attachment(0, 0, SCENE_ATTACHMENT, "application/xml", SCENE_XML.encode())
        writer.add_attachment(0, 0, SPEC_ATTACHMENT, "application/yaml", b"name: tiny\n")
        schema = writer.register_schema("json", "jsonschema", b"{}")
        state, inputs = (
            writer.register_channel(t, "json", schema) for t in ("/sim/state", "/sim/inputs")
        )

        def put(channel: int, message: dict, step: int) -> None:
            writer.add_message(channel, step, json.dumps(message).encode(), step)

        for step in range(STEPS):
            put(state, {"step": step, "t": data.time, "qpos": data.qpos.tolist(),
                        "qvel": data.qvel.tolist(), "act": data.act.tolist()}, step)  # fmt: skip
            data.ctrl[:] = [0.5 * np.sin(20 * data.time), 0.3 * np.cos(15 * data.time)]
            put(inputs, {"step": step, "ctrl": data.ctrl.tolist(), "xfrc": {}}, step)
            mujoco.mj_step(model, data)
        writer.add_metadata(METADATA_NAME, {**METADATA, "outcome": "complete"})
        writer.finish()
    report = verify_log(path)
    assert report.ok and report.damage == "" and report.n_logged == report.n_steps == STEPS
