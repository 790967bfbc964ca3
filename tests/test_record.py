"""Tests of walkrepro.log.record: the MCAP log contract, written and read back."""

from __future__ import annotations

import collections
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from google.protobuf.json_format import MessageToDict
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from walkrepro.errors import UnknownNameError, WalkreproError
from walkrepro.log import record
from walkrepro.log.record import (
    OUTCOME_NOT_CLOSED,
    TOPIC_CONTACTS,
    TOPIC_EVENTS,
    TOPIC_FRAMES,
    TOPIC_INPUTS,
    TOPIC_SCENE,
    TOPIC_SENSORS,
    TOPIC_SIGNALS,
    TOPIC_STATE,
    TOPICS,
    LogWriter,
    read_log,
)

# A free box dropped on the floor, next to a 1-link pendulum with a motor.
SCENE_XML = """
<mujoco model="tiny">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1"/>
    <body name="box" pos="0.8 0 0.1">
      <freejoint/>
      <geom type="box" size="0.05 0.05 0.05" mass="1"/>
    </body>
    <body name="link" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
    </body>
  </worldbody>
  <actuator><motor name="m" joint="hinge"/></actuator>
</mujoco>
"""
SPEC_YAML = "name: tiny\nseed: 7\nsim:\n  timestep: 0.002\n"
METADATA = {"git_commit": "abc1234", "seed": "7", "experiment": "tiny"}
STEPS = 300
CONTROL_EVERY = 4  # control ticks every 4 physics steps (500 Hz)
FRAMES_EVERY = 20  # /frames every 20 physics steps (25 Hz)
#: The topics simulate() writes messages to and compares (Foxglove's are tested apart).
DATA_TOPICS = TOPICS[:6]
BINARY_TOPICS = (TOPIC_STATE, TOPIC_INPUTS, TOPIC_CONTACTS, TOPIC_SENSORS, TOPIC_SIGNALS)


def new_writer(path: Path, **kwargs: Any) -> LogWriter:
    return LogWriter(path, scene_xml=SCENE_XML, spec_yaml=SPEC_YAML, metadata=METADATA, **kwargs)


def simulate(log: LogWriter, steps: int = STEPS) -> dict[str, list[dict]]:
    """Simulates the scene, writing every topic per the contract; returns what it wrote."""
    model = mujoco.MjModel.from_xml_string(SCENE_XML)
    data = mujoco.MjData(model)
    floor = model.geom("floor").id
    written: dict[str, list[dict]] = {topic: [] for topic in TOPICS}

    def write(topic: str, message: dict, t: float) -> None:
        log.write(topic, message, t)
        # What a reader must get back: numpy turned into plain Python numbers.
        written[topic].append(json.loads(json.dumps(message, default=np.ndarray.tolist)))

    for step in range(steps):
        t = data.time
        write(TOPIC_STATE, {"step": step, "t": t, "qpos": data.qpos.copy(),
                            "qvel": data.qvel.copy(), "act": data.act.copy()}, t)  # fmt: skip
        if step % FRAMES_EVERY == 0:
            log.write_frames(t, data.xpos, data.xquat)
            written[TOPIC_FRAMES].append({})
        if step % CONTROL_EVERY == 0:
            ctrl = 0.3 * math.sin(10 * t)
            write(TOPIC_SENSORS, {"q": data.qpos[7:].copy(), "gyro": [0.1, -0.0, 1e-300]}, t)
            write(TOPIC_SIGNALS, {"t": t, "u": ctrl, "ref": [t / 3, 0.1 + 0.2]}, t)
        data.ctrl[:] = ctrl
        xfrc = {"box": [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]} if 50 <= step < 60 else {}
        data.xfrc_applied[:] = 0.0
        for name, wrench in xfrc.items():
            data.xfrc_applied[model.body(name).id] = wrench
        write(TOPIC_INPUTS, {"step": step, "ctrl": data.ctrl.copy(), "xfrc": xfrc}, t)
        if step == 50:
            write(TOPIC_EVENTS, {"t": t, "kind": "push", "body": "box"}, t)
        mujoco.mj_step(model, data)
        pairs: dict[str, list[float]] = {}
        for i in range(data.ncon):
            contact = data.contact[i]
            if floor not in (contact.geom1, contact.geom2):
                continue
            local = np.zeros(6)
            mujoco.mj_contactForce(model, data, i, local)  # geom1 on geom2, contact frame
            sign = 1.0 if contact.geom1 == floor else -1.0
            force_w = sign * contact.frame.reshape(3, 3).T @ local[:3]  # on the box [N]
            wrench = np.concatenate([force_w, np.cross(contact.pos, force_w)])  # about O_w
            pairs["box/floor"] = (np.add(pairs.get("box/floor", 0.0), wrench)).tolist()
        if pairs:
            write(TOPIC_CONTACTS, {"step": step, "t": data.time, "pairs": pairs}, data.time)
    return written


def as_bits(obj: Any) -> Any:
    """Floats as their exact hex spelling, so == compares bit for bit (-0.0 != 0.0)."""
    if isinstance(obj, dict):
        return {key: as_bits(value) for key, value in obj.items()}
    if isinstance(obj, list):
        return [as_bits(value) for value in obj]
    if isinstance(obj, float):
        return obj.hex()
    return obj


def use_encoder(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    """Selects the stdlib or the (optional) orjson JSON backend of walkrepro.log.record."""
    if name == "orjson":
        orjson = pytest.importorskip("orjson")
        monkeypatch.setattr(record, "orjson", orjson)
        monkeypatch.setattr(record, "_encode", record._encode_orjson)
        monkeypatch.setattr(record, "_decode_json", orjson.loads)
    else:
        monkeypatch.setattr(record, "_encode", record._encode_stdlib)
        monkeypatch.setattr(record, "_decode_json", json.loads)


@pytest.fixture(params=["stdlib", "orjson"])
def encoder(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    use_encoder(monkeypatch, request.param)
    return request.param


@pytest.fixture(scope="module", params=["stdlib", "orjson"])
def written_log(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[Path, dict[str, list[dict]]]]:
    """A 300-step log written (and read back) with each JSON backend."""
    with pytest.MonkeyPatch.context() as monkeypatch:
        use_encoder(monkeypatch, request.param)
        path = tmp_path_factory.mktemp("log") / "run.mcap"
        with new_writer(path, chunk_size=16 << 10) as log:
            written = simulate(log)
            log.close("fell", {"fall_time": "0.5"})
        yield path, written


def test_messages_round_trip_bit_exact(written_log: tuple[Path, dict]) -> None:
    """Every message on every topic reads back in order with bit-identical floats."""
    path, written = written_log
    log = read_log(path)
    for topic in DATA_TOPICS:
        assert written[topic], topic
        assert as_bits(log.messages(topic)) == as_bits(written[topic]), topic
    # /sensors and /controller/signals: added at their first message
    assert log.topics() == [*TOPICS[:3], *TOPICS[5:], TOPIC_SENSORS, TOPIC_SIGNALS]
    assert log.messages(TOPIC_SENSORS)[0]["gyro"][1].hex() == "-0x0.0p+0"
    assert log.count(TOPIC_FRAMES) == STEPS // FRAMES_EVERY and log.count(TOPIC_SCENE) == 1
    assert log.log_format == record.LOG_FORMAT == log.metadata["log_format"] == "2"


def test_attachments_and_metadata_round_trip(written_log: tuple[Path, dict]) -> None:
    """scene.xml (loadable alone), spec.yaml and the closing metadata read back exactly."""
    path, _ = written_log
    log = read_log(path)
    assert log.scene_xml == SCENE_XML
    assert log.spec_yaml == SPEC_YAML
    assert mujoco.MjModel.from_xml_string(log.scene_xml).nq == 8
    assert not log.truncated
    meta = log.metadata
    assert meta["outcome"] == "fell" and meta["fall_time"] == "0.5"
    assert {key: meta[key] for key in METADATA} == METADATA
    assert meta["mujoco_version"] == mujoco.__version__
    for key in ("version", "pinocchio_version", "start_time"):
        assert meta[key], key
    assert meta["start_time"].endswith("+00:00")


def test_mcap_records_follow_contract(written_log: tuple[Path, dict]) -> None:
    """Numeric and Foxglove topics (signals too) are protobuf with a FileDescriptorSet
    schema, events JSON with a jsonschema; zstd chunks; stamps are the run's UTC start plus the
    payload's simulated time; per-channel sequences count from 0."""
    path, _ = written_log
    protobuf_topics = (*BINARY_TOPICS, TOPIC_FRAMES, TOPIC_SCENE)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        assert {chunk.compression for chunk in summary.chunk_indexes} == {"zstd"}
        assert len(summary.chunk_indexes) > 1
        media = {a.name: a.media_type for a in summary.attachment_indexes}
        assert media == {"scene.xml": "application/xml", "spec.yaml": "application/yaml"}
        metadata = {m.name: m for m in reader.iter_metadata()}["walkrepro"].metadata
        origin = int(metadata["log_time_origin"])
        assert abs(origin / 1e9 - time.time()) < 3600  # wall-clock UTC, not 1970
        counters: dict[str, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert schema is not None
            if channel.topic in protobuf_topics:
                assert (channel.message_encoding, schema.encoding) == ("protobuf", "protobuf")
                if channel.topic in BINARY_TOPICS:
                    decoded = MessageToDict(_decode_protobuf(schema, message.data))
                else:
                    decoded = {}
            else:
                assert (channel.message_encoding, schema.encoding) == ("json", "jsonschema")
                decoded = json.loads(message.data)
            if "t" in decoded:
                assert (
                    message.log_time == message.publish_time == origin + round(decoded["t"] * 1e9)
                )
            assert message.sequence == counters.get(channel.topic, 0)
            counters[channel.topic] = message.sequence + 1
    assert set(counters) == set(TOPICS)


_DECODERS = DecoderFactory()


def _decode_protobuf(schema: Any, data: bytes) -> Any:
    """A message decoded by mcap-protobuf-support from the schema in the file."""
    decoder = _DECODERS.decoder_for("protobuf", schema)
    assert decoder is not None
    return decoder(data)


def test_messages_satisfy_their_schemas(written_log: tuple[Path, dict]) -> None:
    """Each JSON channel's schema is valid and accepts every message written on it; each
    protobuf message decodes with mcap-protobuf-support to what walkrepro reads."""
    jsonschema = pytest.importorskip("jsonschema")
    path, written = written_log
    validators: dict[int, Any] = {}
    decoded: dict[str, list[Any]] = collections.defaultdict(list)
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if schema.encoding == "protobuf":
                decoded[channel.topic].append(_decode_protobuf(schema, message.data))
                continue
            if schema.id not in validators:
                spec = json.loads(schema.data)
                jsonschema.Draft202012Validator.check_schema(spec)
                validators[schema.id] = jsonschema.Draft202012Validator(spec)
            validators[schema.id].validate(json.loads(message.data))
    assert len(validators) == 1
    states = decoded[TOPIC_STATE]
    assert [list(m.qpos) for m in states] == [m["qpos"] for m in written[TOPIC_STATE]]
    assert [m.step for m in states] == list(range(STEPS))
    pushed = [m for m in decoded[TOPIC_INPUTS] if m.xfrc]
    assert [(m.step, m.xfrc[0].name, list(m.xfrc[0].wrench)) for m in pushed] == [
        (step, "box", [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]) for step in range(50, 60)
    ]
    assert [list(m.gyro) for m in decoded[TOPIC_SENSORS]][0] == [0.1, -0.0, 1e-300]
    signals = decoded[TOPIC_SIGNALS]
    assert [(m.t, m.u, list(m.ref)) for m in signals] == [
        (m["t"], m["u"], m["ref"]) for m in written[TOPIC_SIGNALS]
    ]


def _schema_of(path: Path, topic: str) -> bytes:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    channel = next(c for c in summary.channels.values() if c.topic == topic)
    return summary.schemas[channel.schema_id].data


def test_numpy_values_are_written_exactly(tmp_path: Path, encoder: str) -> None:
    """numpy arrays and scalars become plain JSON numbers with their exact values; null is kept."""
    path = tmp_path / "np.mcap"
    with new_writer(path) as log:
        log.write(
            TOPIC_EVENTS,
            {"t": np.float64(0.25), "kind": "x", "a": np.array([[0.1, 2.0], [3.0, 5e-324]]),
             "f32": np.float32(0.1), "i": np.int64(3), "b": np.bool_(True), "none": None,
             "s": "null"},
            0.25,
        )  # fmt: skip
    (message,) = read_log(path).messages(TOPIC_EVENTS)
    assert message == {"t": 0.25, "kind": "x", "a": [[0.1, 2.0], [3.0, 5e-324]],
                       "f32": float(np.float32(0.1)), "i": 3, "b": True, "none": None,
                       "s": "null"}  # fmt: skip


def test_signals_keep_their_kinds_and_leave_out_what_is_undefined(tmp_path: Path) -> None:
    """Signals are laid out by the first tick: numpy and Python numbers keep their values
    (integers stay integers), arrays their bits; a scalar a later tick leaves out (or sets to
    NaN) is not in that tick's message; a new name, another shape, a string are errors."""
    from walkrepro.log.signals import SignalLayout, Signals

    path = tmp_path / "signals.mcap"
    with new_writer(path) as log:
        log.write_signals(0.0, {"i": np.int64(3), "f32": np.float32(0.1), "a": [0.1, -0.0],
                                "x": 1e300})  # fmt: skip
        log.write_signals(0.5, {"i": 4, "f32": 0.2, "a": np.array([5e-324, 2.0])})  # x left out
        log.write_signals(1.0, {"i": 5, "f32": float("nan"), "a": [1.0, 2.0], "x": 0.0})
        for bad, match in (
            ({"i": 1, "new": 1.0}, "not in the layout"),
            ({"i": 1, "a": [1.0]}, "shape"),
            ({"f32": 1.0}, "integer signal"),
        ):
            with pytest.raises(ValueError, match=match):
                log.write_signals(1.5, bad)
    messages = read_log(path).messages(TOPIC_SIGNALS)
    assert messages == [
        {"t": 0.0, "i": 3, "f32": float(np.float32(0.1)), "a": [0.1, -0.0], "x": 1e300},
        {"t": 0.5, "i": 4, "f32": 0.2, "a": [5e-324, 2.0]},
        {"t": 1.0, "i": 5, "a": [1.0, 2.0], "x": 0.0},
    ]
    assert type(messages[0]["i"]) is int and math.copysign(1, messages[0]["a"][1]) < 0
    with new_writer(tmp_path / "s.mcap") as log, pytest.raises(ValueError, match="a signal is"):
        log.write_signals(0.0, {"s": "text"})
    layout = SignalLayout([("k", 0, True), ("v", 2, False)])
    signals = Signals(layout, np.array([2.0, np.nan, np.nan]))
    assert dict(signals) == {"k": 2} and "v" not in signals


def _cut(path: Path, size: int, tmp_path: Path) -> Path:
    cut = tmp_path / f"cut-{size}.mcap"
    cut.write_bytes(path.read_bytes()[:size])
    return cut


def test_truncated_log_keeps_complete_chunks(
    written_log: tuple[Path, dict], tmp_path: Path
) -> None:
    """A file cut anywhere after its attachments reads back a prefix of every topic."""
    path, written = written_log
    size = path.stat().st_size
    n_states = []
    for fraction in (0.2, 0.5, 0.8):
        log = read_log(_cut(path, int(size * fraction), tmp_path))
        assert log.truncated
        assert log.metadata == {"outcome": OUTCOME_NOT_CLOSED}
        assert log.scene_xml == SCENE_XML and log.spec_yaml == SPEC_YAML
        for topic in DATA_TOPICS:
            got = log.messages(topic)
            assert as_bits(got) == as_bits(written[topic][: len(got)]), topic
        n_states.append(len(log.messages(TOPIC_STATE)))
    assert 0 < n_states[0] < n_states[1] < n_states[2] < STEPS


def test_log_cut_after_metadata_keeps_outcome(
    written_log: tuple[Path, dict], tmp_path: Path
) -> None:
    """A file that lost only its summary and footer keeps all messages and its outcome."""
    path, _ = written_log
    data = path.read_bytes()
    # Footer: opcode (1) + length (8) + summary_start (8) + ... (20), then the 8-byte magic.
    footer = len(data) - 8 - 29
    summary_start = int.from_bytes(data[footer + 9 : footer + 17], "little")
    assert 0 < summary_start < footer
    log = read_log(_cut(path, summary_start, tmp_path))
    assert log.truncated
    assert log.metadata["outcome"] == "fell"
    assert len(log.messages(TOPIC_STATE)) == STEPS


def test_damaged_chunk_stops_the_read_there(written_log: tuple[Path, dict], tmp_path: Path) -> None:
    """Garbage inside a chunk is detected; only the messages of the chunks before it are kept."""
    path, written = written_log
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    chunk = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)[2]
    data = bytearray(path.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle : middle + 64] = bytes(range(64))
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    states = read_log(damaged).messages(TOPIC_STATE)
    assert 0 < len(states) < STEPS
    assert as_bits(states) == as_bits(written[TOPIC_STATE][: len(states)])


def test_missing_or_foreign_file_is_a_clear_error(tmp_path: Path) -> None:
    """A missing, empty or non-MCAP file raises WalkreproError naming the problem."""
    with pytest.raises(WalkreproError, match="cannot read log"):
        read_log(tmp_path / "nope.mcap")
    text = tmp_path / "notes.mcap"
    text.write_text("just some text, not a log\n")
    with pytest.raises(WalkreproError, match="not an MCAP log"):
        read_log(text)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(WalkreproError, match="not an MCAP log"):
        read_log(empty)


def test_unknown_topic_is_rejected(tmp_path: Path) -> None:
    """Writing to a topic outside the contract raises ValueError listing the valid topics."""
    with new_writer(tmp_path / "a.mcap") as log, pytest.raises(ValueError, match="/sim/state"):
        log.write("/sim/stat", {"t": 0.0}, 0.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_numbers(tmp_path: Path, bad: float, encoder: str) -> None:
    """The binary topics keep any float64 (NaN too) bit for bit; on the JSON topic NaN/inf
    raise a ValueError naming the entry, and nothing invalid reaches the file."""
    path = tmp_path / "a.mcap"
    with new_writer(path) as log:
        qpos = np.zeros(8)
        qpos[3] = bad
        state = {"step": 0, "t": 0.0, "qpos": qpos, "qvel": np.zeros(7), "act": []}
        log.write(TOPIC_STATE, state, 0.0)
        with pytest.raises(ValueError, match=r"ref\[1\]"):
            log.write(TOPIC_EVENTS, {"t": 0.0, "kind": "x", "ref": [0.0, bad]}, 0.0)
        with pytest.raises(ValueError, match="finite"):
            log.write(TOPIC_EVENTS, {"t": 0.0, "kind": "x"}, bad)
        log.write(TOPIC_EVENTS, {"t": 0.0, "kind": "ok"}, 0.0)  # the writer is still usable
    log_read = read_log(path)
    (read_state,) = log_read.messages(TOPIC_STATE)
    assert np.asarray(read_state["qpos"]).tobytes() == qpos.tobytes()
    assert log_read.messages(TOPIC_EVENTS) == [{"t": 0.0, "kind": "ok"}]
    assert log_read.metadata["outcome"] == "complete"


def test_malformed_sim_messages_are_rejected(tmp_path: Path) -> None:
    """State/input vectors must fit the scene and xfrc must name real bodies."""
    with new_writer(tmp_path / "a.mcap") as log:
        with pytest.raises(ValueError, match="qvel has 6 entries, the scene has 7"):
            log.write(TOPIC_STATE, {"step": 0, "t": 0.0, "qpos": [0.0] * 8, "qvel": [0.0] * 6,
                                    "act": []}, 0.0)  # fmt: skip
        with pytest.raises(ValueError, match="lacks key"):
            log.write(TOPIC_INPUTS, {"step": 0, "ctrl": [0.0]}, 0.0)
        with pytest.raises(UnknownNameError, match="link"):
            log.write(TOPIC_INPUTS, {"step": 0, "ctrl": [0.0], "xfrc": {"bx": [0.0] * 6}}, 0.0)


def test_context_manager_records_error_outcome(tmp_path: Path) -> None:
    """An exception inside the with-block closes the log with outcome 'error' and the message."""
    path = tmp_path / "a.mcap"
    with pytest.raises(RuntimeError, match="solver blew up"), new_writer(path) as log:
        simulate(log, steps=20)
        raise RuntimeError("solver blew up")
    read = read_log(path)
    assert read.metadata["outcome"] == "error"
    assert read.metadata["error"] == "RuntimeError: solver blew up"
    assert len(read.messages(TOPIC_STATE)) == 20


def test_close_is_idempotent_and_validated(tmp_path: Path) -> None:
    """close() rejects unknown outcomes, then writes once; later calls and writes change nothing."""
    path = tmp_path / "a.mcap"
    log = new_writer(path)
    with pytest.raises(ValueError, match="complete, fell, interrupted, error"):
        log.close("crashed")
    log.close("interrupted")
    log.close("complete")
    assert log.closed
    with pytest.raises(ValueError, match="closed"):
        log.write(TOPIC_SIGNALS, {"t": 0.0}, 0.0)
    assert read_log(path).metadata["outcome"] == "interrupted"


def test_writer_validates_metadata_and_scene(tmp_path: Path) -> None:
    """Missing metadata keys, a reserved 'outcome' key, or a scene that needs files are refused."""
    path = tmp_path / "a.mcap"
    with pytest.raises(ValueError, match="git_commit"):
        LogWriter(
            path, scene_xml=SCENE_XML, spec_yaml="", metadata={"seed": "1", "experiment": "x"}
        )
    with pytest.raises(ValueError, match="outcome"):
        LogWriter(path, scene_xml=SCENE_XML, spec_yaml="", metadata={**METADATA, "outcome": "x"})
    with pytest.raises(TypeError, match="str to str"):
        LogWriter(path, scene_xml=SCENE_XML, spec_yaml="", metadata={**METADATA, "seed": 7})
    needs_file = SCENE_XML.replace(
        "<worldbody>", '<asset><mesh name="m" file="foot.stl"/></asset><worldbody>'
    )
    with pytest.raises(WalkreproError, match="mesh"):
        LogWriter(path, scene_xml=needs_file, spec_yaml="", metadata=METADATA)
    with pytest.raises(WalkreproError, match="does not load"):
        LogWriter(path, scene_xml="<mujoco><bad/></mujoco>", spec_yaml="", metadata=METADATA)
    with pytest.raises(WalkreproError, match="cannot write"):
        LogWriter(tmp_path / "no" / "dir.mcap", scene_xml=SCENE_XML, spec_yaml="",
                  metadata=METADATA)  # fmt: skip


def test_unknown_topic_on_read_lists_topics(written_log: tuple[Path, dict]) -> None:
    """Asking a log for a topic it cannot have raises UnknownNameError listing real ones."""
    path, _ = written_log
    with pytest.raises(UnknownNameError, match="/sim/inputs"):
        read_log(path).messages("/sim/input")


def test_fast_paths_write_the_same_bytes_as_write(tmp_path: Path, encoder: str) -> None:
    """The simulation loop's fast paths (float64 arrays as they are, ctrl encoded once per
    tick) give byte for byte the messages :meth:`LogWriter.write` gives, and still check."""
    model = mujoco.MjModel.from_xml_string(SCENE_XML)
    rng = np.random.default_rng(0)
    qpos, qvel, ctrl = rng.standard_normal(8), rng.standard_normal(7), rng.standard_normal(1)
    xfrc = {"box": rng.standard_normal(6)}
    state = {"step": 3, "t": 0.006, "qpos": qpos, "qvel": qvel, "act": np.zeros(model.na)}
    paths = tmp_path / "slow.mcap", tmp_path / "fast.mcap"
    origin = 1_700_000_000_000_000_000
    with (
        new_writer(paths[0], log_time_origin=origin) as slow,
        new_writer(paths[1], log_time_origin=origin) as fast,
    ):
        slow.write(TOPIC_STATE, state, 0.006)
        fast.write_state(3, 0.006, qpos, qvel, state["act"])
        for step, wrenches in ((3, {}), (4, xfrc)):
            slow.write(TOPIC_INPUTS, {"step": step, "ctrl": ctrl, "xfrc": wrenches}, 0.006)
            fast.write_inputs(step, fast.encode_ctrl(ctrl), wrenches, 0.006)
        with pytest.raises(ValueError, match="ctrl has 2 entries, the scene has 1"):
            fast.encode_ctrl(np.zeros(2))
        with pytest.raises(ValueError, match=r"\[0\] = nan"):
            fast.encode_ctrl(np.array([math.nan]))
        with pytest.raises(UnknownNameError, match="link"):
            fast.write_inputs(5, fast.encode_ctrl(ctrl), {"bx": np.zeros(6)}, 0.008)
        with pytest.raises(ValueError, match="qvel has 6 entries"):
            fast.write_state(3, 0.006, qpos, qvel[:6], state["act"])
    raw = [_raw_messages(path) for path in paths]
    assert raw[0] == raw[1] and len(raw[0]) == 4  # the scene, a state, two inputs


def test_summary_statistics_and_indexes_point_at_the_messages(
    written_log: tuple[Path, dict],
) -> None:
    """The summary's statistics count every message, each chunk index points at its chunk,
    and each message index entry points at a message of that channel and time."""
    import struct

    import zstandard

    path, written = written_log
    raw = path.read_bytes()
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    stats = summary.statistics
    counts = {topic: len(m) for topic, m in written.items() if m}
    counts[TOPIC_SCENE] = 1  # written by the writer itself
    assert stats.message_count == sum(counts.values())
    by_topic = {summary.channels[i].topic: n for i, n in stats.channel_message_counts.items()}
    assert by_topic == counts
    assert stats.chunk_count == len(summary.chunk_indexes)
    assert stats.attachment_count == 2 and stats.metadata_count == 1
    indexed = 0
    for chunk_index in summary.chunk_indexes:
        start = chunk_index.chunk_start_offset
        assert raw[start] == 0x06  # a Chunk record
        (record_length,) = struct.unpack_from("<Q", raw, start + 1)
        assert chunk_index.chunk_length == 9 + record_length
        # Chunk body: start, end, uncompressed size, crc, compression string, records.
        body = start + 9 + 8 + 8 + 8 + 4
        (n,) = struct.unpack_from("<I", raw, body)
        (size,) = struct.unpack_from("<Q", raw, body + 4 + n)
        records = zstandard.ZstdDecompressor().decompress(
            raw[body + 12 + n : body + 12 + n + size],
            max_output_size=chunk_index.uncompressed_size,
        )
        for channel_id, offset in chunk_index.message_index_offsets.items():
            assert raw[offset] == 0x07  # a MessageIndex record
            (count_bytes,) = struct.unpack_from("<I", raw, offset + 11)
            entries = struct.unpack_from(f"<{count_bytes // 8}Q", raw, offset + 15)
            for log_time, at in zip(entries[::2], entries[1::2], strict=True):
                opcode, _, channel, _, stamp = struct.unpack_from("<BQHIQ", records, at)
                assert (opcode, channel, stamp) == (0x05, channel_id, log_time)
                assert chunk_index.message_start_time <= stamp <= chunk_index.message_end_time
                indexed += 1
    assert indexed == stats.message_count


def test_sensor_fields_keep_their_kind(tmp_path: Path, encoder: str) -> None:
    """``/sensors`` is laid out by its first message: None fields read back as None, numbers
    as numbers, arrays as lists; a later message of another shape is refused."""
    path = tmp_path / "a.mcap"
    first = {"t": 0.5, "base_pos": None, "q": np.array([1.0, 2.0])}
    with new_writer(path) as log:
        log.write(TOPIC_SENSORS, first, 0.5)
        log.write(TOPIC_SENSORS, {"t": 0.0, "base_pos": None, "q": [0.0, -0.0]}, 0.5)
        with pytest.raises(ValueError, match="keys"):
            log.write(TOPIC_SENSORS, {"t": 0.5, "q": np.zeros(2)}, 0.5)
        with pytest.raises(ValueError, match="changed kind"):
            log.write(TOPIC_SENSORS, {**first, "base_pos": np.zeros(3)}, 0.5)
        with pytest.raises(ValueError, match="changed kind"):
            log.write(TOPIC_SENSORS, {**first, "q": np.zeros(3)}, 0.5)
    with new_writer(tmp_path / "b.mcap") as other, pytest.raises(ValueError, match="a sensor"):
        other.write(TOPIC_SENSORS, {"x": "text"}, 0.0)
    assert as_bits(read_log(path).messages(TOPIC_SENSORS)) == as_bits(
        [{"t": 0.5, "base_pos": None, "q": [1.0, 2.0]}, {"t": 0.0, "base_pos": None,
                                                        "q": [0.0, -0.0]}]
    )  # fmt: skip


def _raw_messages(path: Path) -> list[tuple[int, int, int, int, bytes]]:
    """Every message's channel, sequence, log and publish time, and data, in file order."""
    with open(path, "rb") as f:
        messages = make_reader(f).iter_messages(log_time_order=False)
        return [
            (m.channel_id, m.sequence, m.log_time, m.publish_time, m.data) for _, _, m in messages
        ]


def test_write_signals_writes_the_bytes_of_write(tmp_path: Path, encoder: str) -> None:
    """write_signals(t, signals) gives byte for byte what write() gives {"t": t, **signals},
    from a dict or from Signals of the same layout."""
    from walkrepro.log.signals import SignalLayout, Signals

    layout = SignalLayout([("state", 0, True), ("com", 3, False), ("v", 0, False)])
    cases: list[tuple[Any, dict[str, Any]]] = [
        (0.0005, {"state": 2, "com": [0.1, -2.5e-7, 0.0], "v": 1e300}),
        (np.float64(0.001), {"state": np.int64(3), "com": np.array([-0.0, 1.0, 2.0]), "v": -0.0}),
        (0.002, {"state": 0, "com": (1, 2, 3)}),  # v not defined at this tick
    ]
    paths = tmp_path / "write.mcap", tmp_path / "signals.mcap", tmp_path / "vector.mcap"
    origin = 1_700_000_000_000_000_000
    with (
        new_writer(paths[0], log_time_origin=origin) as slow,
        new_writer(paths[1], log_time_origin=origin) as fast,
        new_writer(paths[2], log_time_origin=origin) as vector,
    ):
        for t, signals in cases:
            slow.write(TOPIC_SIGNALS, {"t": t, **signals}, t)
            fast.write_signals(t, signals)
            vector.write_signals(t, Signals.of(layout, signals))
    raw = [_raw_messages(path) for path in paths]
    assert raw[0] == raw[1] == raw[2] and len(raw[0]) == len(cases) + 1  # and the scene


def test_a_dict_of_scalar_signals_writes_the_bytes_of_write(tmp_path: Path, encoder: str) -> None:
    """A dict of plain numbers in the layout's order (copied without building a vector)
    gives byte for byte what write() gives; a dict in another order, with a scalar left
    out, or with an array where a number belongs goes through the checked path."""
    cases: list[tuple[float, dict[str, Any]]] = [
        (0.0005, {"err": 0.25, "phase": 2, "ok": True}),
        (0.001, {"err": -0.0, "phase": 3, "ok": False}),
        (0.0015, {"phase": 1, "err": np.float64(1e300), "ok": 1}),  # another order
        (0.002, {"phase": 0, "ok": 0}),  # err not defined at this tick
        (0.0025, {"err": 5e-324, "phase": -4, "ok": 1}),
    ]
    paths = tmp_path / "write.mcap", tmp_path / "signals.mcap"
    origin = 1_700_000_000_000_000_000
    with (
        new_writer(paths[0], log_time_origin=origin) as slow,
        new_writer(paths[1], log_time_origin=origin) as fast,
    ):
        for t, signals in cases:
            slow.write(TOPIC_SIGNALS, {"t": t, **signals}, t)
            fast.write_signals(t, signals)
        with pytest.raises(ValueError, match="'err' is an array"):
            fast.write_signals(0.003, {"err": np.zeros(2), "phase": 1, "ok": 1})
    raw = [_raw_messages(path) for path in paths]
    assert raw[0] == raw[1] and len(raw[0]) == len(cases) + 1  # and the scene


def test_contact_pairs_keep_their_order_as_the_pair_set_changes(tmp_path: Path) -> None:
    """Contacts are gathered per set of pairs; as the set changes every few ticks (and comes
    back), the messages read back in order, with their names, values and sequence numbers."""
    path = tmp_path / "contacts.mcap"
    sets = [("a/floor",), ("a/floor",), ("a/floor", "b/floor"), (), ("b/floor",), ("a/floor",)]
    rng = np.random.default_rng(3)
    written = []
    with new_writer(path, chunk_size=4 << 10) as log:
        for k in range(60):
            names = sets[k % len(sets)]
            wrenches = rng.standard_normal((len(names), 6))
            log.write_contact_pairs(k, k * 0.002, names, wrenches)
            written.append({"step": k, "t": k * 0.002,
                            "pairs": dict(zip(names, wrenches.tolist(), strict=True))})  # fmt: skip
    assert as_bits(read_log(path).messages(TOPIC_CONTACTS)) == as_bits(written)
    sequences = [m[1] for m in _raw_messages(path) if m[0] == 3]
    assert sequences == list(range(60))


def test_write_signals_still_checks(tmp_path: Path, encoder: str) -> None:
    """write_signals refuses a non-mapping, a bad time and a closed log."""
    log = new_writer(tmp_path / "a.mcap")
    with pytest.raises(TypeError):
        log.write_signals(0.0, [("ok", 1.0)])  # type: ignore[arg-type]
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="finite and >= 0"):
            log.write_signals(bad, {"ok": 1.0})
    log.write_signals(0.0, {"ok": 1.0})
    log.close("complete")
    with pytest.raises(ValueError, match="closed"):
        log.write_signals(0.0, {"ok": 1.0})
    assert read_log(tmp_path / "a.mcap").messages(TOPIC_SIGNALS) == [{"t": 0.0, "ok": 1.0}]


def test_every_write_method_checks_like_write(tmp_path: Path, encoder: str) -> None:
    """The fast paths keep write()'s checks: topic, keys, sizes, time, closed."""
    log = new_writer(tmp_path / "a.mcap")
    state = (0, 0.0, np.zeros(8), np.zeros(7), np.zeros(0))
    ctrl = log.encode_ctrl(np.zeros(1))
    with pytest.raises(ValueError, match="unknown topic"):
        log.write("/sensor", {"q": np.zeros(2)}, 0.0)
    with pytest.raises(ValueError, match="unknown topic"):
        log.write(TOPIC_FRAMES, {"t": 0.0}, 0.0)
    with pytest.raises(ValueError, match="lacks key"):
        log.write(TOPIC_SIGNALS, {"u": 1.0}, 0.0)
    with pytest.raises(ValueError, match="lacks key"):
        log.write(TOPIC_CONTACTS, {"step": 0, "t": 0.0}, 0.0)
    with pytest.raises(ValueError, match="qpos has 7 entries"):
        log.write(TOPIC_STATE, {"step": 0, "t": 0.0, "qpos": np.zeros(7),
                                        "qvel": np.zeros(7), "act": np.zeros(0)}, 0.0)  # fmt: skip
    with pytest.raises(ValueError, match="must have 6 entries"):
        log.write_inputs(0, ctrl, {"box": np.zeros(5)}, 0.0)
    for bad in (-0.5, math.nan, math.inf):
        with pytest.raises(ValueError, match="finite"):
            log.write_state(*state[:1], bad, *state[2:])
        with pytest.raises(ValueError, match="finite and >= 0"):
            log.write_inputs(0, ctrl, {}, bad)
        with pytest.raises(ValueError, match="finite and >= 0"):
            log.write(TOPIC_SENSORS, {"q": np.zeros(2)}, bad)
        with pytest.raises(ValueError, match="finite and >= 0"):
            log.write_frames(bad, np.zeros((3, 3)), np.zeros((3, 4)))
    log.write_state(*state)
    log.close("complete")
    for write in (
        lambda: log.write_state(*state),
        lambda: log.write_inputs(0, ctrl, {}, 0.0),
        lambda: log.write(TOPIC_SENSORS, {"q": np.zeros(2)}, 0.0),
        lambda: log.write(TOPIC_EVENTS, {"t": 0.0, "kind": "x"}, 0.0),
        lambda: log.write_frames(0.0, np.zeros((3, 3)), np.zeros((3, 4))),
    ):
        with pytest.raises(ValueError, match="closed"):
            write()
    read = read_log(tmp_path / "a.mcap")
    assert [read.count(topic) for topic in TOPICS] == [1, 0, 0, 0, 0, 0, 0, 1]


def test_chunks_carry_a_zstd_checksum_in_place_of_the_crc(
    written_log: tuple[Path, dict],
) -> None:
    """Each chunk's records are guarded by its zstd frame's checksum (MCAP's CRC is 0)."""
    import struct

    import zstandard

    path, _ = written_log
    raw = path.read_bytes()
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    for chunk_index in summary.chunk_indexes:
        body = chunk_index.chunk_start_offset + 9
        (crc,) = struct.unpack_from("<I", raw, body + 24)
        frame = raw[body + 44 : body + 44 + chunk_index.compressed_size]
        assert crc == 0
        assert zstandard.get_frame_parameters(frame).has_checksum
        assert len(zstandard.ZstdDecompressor().decompress(frame)) == chunk_index.uncompressed_size


def test_arrays_equal_the_messages(written_log: tuple[Path, dict]) -> None:
    """Log.arrays stacks a flat topic's messages bit for bit (numpy fast path), in order."""
    path, written = written_log
    log = read_log(path)
    states = log.arrays(TOPIC_STATE)
    assert states["step"].tolist() == [m["step"] for m in written[TOPIC_STATE]]
    assert states["qpos"].tobytes() == np.array([m["qpos"] for m in written[TOPIC_STATE]]).tobytes()
    sensors = log.arrays(TOPIC_SENSORS)
    assert sensors["gyro"][0].tobytes() == np.array([0.1, -0.0, 1e-300]).tobytes()
    with pytest.raises(ValueError, match="pairs"):
        log.arrays(TOPIC_CONTACTS)
    with pytest.raises(UnknownNameError):
        log.arrays("/nope")


def test_arrays_of_chosen_fields(written_log: tuple[Path, dict]) -> None:
    """Log.arrays stacks only the fields asked for, so a topic with a map field still reads."""
    path, written = written_log
    contacts = read_log(path).arrays(TOPIC_CONTACTS, ("step", "t"))
    assert sorted(contacts) == ["step", "t"]
    assert contacts["step"].tolist() == [m["step"] for m in written[TOPIC_CONTACTS]]
