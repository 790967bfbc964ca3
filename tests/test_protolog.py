"""Tests of walkrepro.protolog: the numeric topics' protobuf schemas and wire encoders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from walkrepro import protolog

SENSORS = {
    "t": 0.25,
    "joint_pos": np.array([0.1, -0.0, 5e-324]),
    "imu_quat": np.array([1.0, 0.0, 0.0, 0.0]),
    "base_pos": None,
    "empty": np.zeros(0),
}


def _classes(layout=()):  # noqa: ANN001, ANN202
    return protolog.message_classes(protolog.file_descriptor_set(layout))


def _bits(values) -> bytes:  # noqa: ANN001
    return np.asarray(values, dtype=np.float64).tobytes()


def test_state_encoder_is_protobufs_encoding_of_the_same_message() -> None:
    """A SimState written by the encoder parses to the values given, bit for bit, and
    protobuf's own serialization of those values parses to the same message."""
    cls = _classes()["walkrepro.SimState"]
    qpos = np.array([0.1, -0.0, 5e-324, math.nan, 1e300])
    qvel, act = np.arange(4.0), np.zeros(0)
    data = protolog.StateEncoder(5, 4, 0).encode(12345, 0.0005, qpos, qvel, act)
    message = cls.FromString(data)
    assert message.step == 12345 and message.t == 0.0005
    assert _bits(message.qpos) == qpos.tobytes() and _bits(message.qvel) == qvel.tobytes()
    assert list(message.act) == []
    reference = cls(step=12345, t=0.0005, qpos=qpos.tolist(), qvel=qvel.tolist())
    assert data == reference.SerializeToString()


def test_step_zero_and_time_zero_are_written_and_read() -> None:
    """Scalars are always on the wire (protobuf parsers read explicit zeros)."""
    cls = _classes()["walkrepro.SimContacts"]
    data = protolog.ContactsEncoder().encode(0, 0.0, {})
    assert data == b"\x08\x00\x11" + bytes(8)
    assert cls.FromString(data) == cls()


def test_inputs_and_contacts_keep_wrench_names_and_order() -> None:
    """Repeated Wrench entries keep their names, 6 values and order."""
    classes = _classes()
    encoder = protolog.InputsEncoder(2)
    ctrl = encoder.encode_ctrl(np.array([1.5, -2.0]))
    wrenches = {"pelvis": np.arange(6.0), "a/much_longer_name" * 8: [0.0, -0.0, 1, 2, 3, 4]}
    message = classes["walkrepro.SimInputs"].FromString(encoder.encode(7, ctrl, wrenches))
    assert message.step == 7 and list(message.ctrl) == [1.5, -2.0]
    assert [(w.name, _bits(w.wrench)) for w in message.xfrc] == [
        (name, _bits(w)) for name, w in wrenches.items()
    ]
    decode = protolog.dict_decoder(protolog.file_descriptor_set(), "walkrepro.SimContacts")
    contacts = protolog.ContactsEncoder().encode(3, 0.5, wrenches)
    assert decode(contacts) == {
        "step": 3,
        "t": 0.5,
        "pairs": {name: [float(x) for x in w] for name, w in wrenches.items()},
    }
    assert list(decode(contacts)["pairs"]) == list(wrenches)


def test_sensors_layout_follows_the_first_snapshot() -> None:
    """Numbers, arrays and not-provided fields get double, repeated double and NullValue
    fields in the snapshot's order; the decoder gives the snapshot's dict back."""
    layout = protolog.sensors_layout(SENSORS)
    assert layout == (("t", "scalar"), ("joint_pos", "array"), ("imu_quat", "array"),
                      ("base_pos", "null"), ("empty", "array"))  # fmt: skip
    schema = protolog.file_descriptor_set(layout)
    cls = protolog.message_classes(schema)["walkrepro.Sensors"]
    assert [f.name for f in cls.DESCRIPTOR.fields] == [key for key, _ in layout]
    assert cls.DESCRIPTOR.fields_by_name["base_pos"].enum_type.full_name == (
        "google.protobuf.NullValue"
    )
    data = protolog.SensorsEncoder(layout).encode(SENSORS)
    decoded = protolog.dict_decoder(schema, "walkrepro.Sensors")(data)
    assert decoded == {"t": 0.25, "joint_pos": [0.1, -0.0, 5e-324],
                       "imu_quat": [1.0, 0.0, 0.0, 0.0], "base_pos": None, "empty": []}  # fmt: skip
    assert _bits(decoded["joint_pos"]) == SENSORS["joint_pos"].tobytes()


def test_sensors_of_another_shape_are_refused() -> None:
    """A snapshot whose keys or kinds differ from the first one's raises ValueError."""
    encoder = protolog.SensorsEncoder(protolog.sensors_layout(SENSORS))
    with pytest.raises(ValueError, match="keys"):
        encoder.encode({"t": 0.0})
    with pytest.raises(ValueError, match="changed kind"):
        encoder.encode({**SENSORS, "base_pos": np.zeros(3)})
    with pytest.raises(ValueError, match="changed kind"):
        encoder.encode({**SENSORS, "t": np.zeros(2)})
    with pytest.raises(ValueError, match="a sensor field is"):
        protolog.sensors_layout({"flag": True})


def test_varint_matches_protobuf() -> None:
    """Varints of 0, 1, 127, 128, 300 and 2**63 as protobuf spells them."""
    cls = _classes()["walkrepro.SimState"]
    for n in (0, 1, 127, 128, 300, 2**63):
        assert protolog.varint(n) == cls(step=n).SerializeToString()[1:] or n == 0
    assert protolog.varint(0) == b"\x00"


def test_sensors_fast_path_gives_the_same_message() -> None:
    """After the first snapshot, snapshots take the precomputed path; they decode to what the
    general path gives, and a misfit (list, other size, other dtype size) falls back."""
    layout = protolog.sensors_layout(SENSORS)
    schema = protolog.file_descriptor_set(layout)
    decode = protolog.dict_decoder(schema, "walkrepro.Sensors")
    encoder = protolog.SensorsEncoder(layout)
    encoder.encode(SENSORS)
    later = {**SENSORS, "t": 0.5, "joint_pos": np.array([1.0, 2.0, -0.0])}
    assert encoder._fast is not None
    assert decode(encoder.encode(later)) == decode(encoder.encode_any(later))
    for misfit in ([1.0, 2.0, 3.0], np.zeros(4), np.zeros(3, dtype=np.float32)):
        message = {**later, "joint_pos": misfit}
        assert decode(encoder.encode(message))["joint_pos"] == [
            float(x) for x in np.asarray(misfit, dtype=np.float64)
        ]


def test_flat_arrays_read_every_message_bit_for_bit() -> None:
    """flat_arrays gives the values of each message (steps of any varint length, in file
    order), the same as decoding each; not-provided fields are left out."""
    encoder = protolog.StateEncoder(3, 2, 0)
    rng = np.random.default_rng(1)
    steps = [0, 5, 127, 128, 300, 2**40, 1]
    qpos = rng.standard_normal((len(steps), 3))
    qpos[0, 0] = -0.0
    raw = [
        encoder.encode(s, s * 1e-3, q, q[:2], np.zeros(0)) for s, q in zip(steps, qpos, strict=True)
    ]
    cls = _classes()["walkrepro.SimState"]
    arrays = protolog.flat_arrays(raw, cls.DESCRIPTOR)
    assert arrays is not None
    assert arrays["step"].tolist() == steps
    assert arrays["qpos"].tobytes() == qpos.tobytes() and arrays["act"].shape == (7, 0)
    assert arrays["t"].tolist() == [s * 1e-3 for s in steps]
    layout = protolog.sensors_layout(SENSORS)
    sensors = protolog.message_classes(protolog.file_descriptor_set(layout))["walkrepro.Sensors"]
    got = protolog.flat_arrays([protolog.SensorsEncoder(layout).encode(SENSORS)] * 2,
                               sensors.DESCRIPTOR)  # fmt: skip
    assert got is not None and "base_pos" not in got and got["imu_quat"].shape == (2, 4)


def test_flat_arrays_refuse_what_does_not_fit() -> None:
    """Sub-messages, ragged arrays and foreign bytes give None (callers decode one by one)."""
    classes = _classes()
    contacts = protolog.ContactsEncoder().encode(1, 0.5, {"a/b": np.zeros(6)})
    assert protolog.flat_arrays([contacts], classes["walkrepro.SimContacts"].DESCRIPTOR) is None
    state = classes["walkrepro.SimState"].DESCRIPTOR
    short = protolog.StateEncoder(2, 2, 0).encode(1, 0.0, np.zeros(2), np.zeros(2), np.zeros(0))
    long = protolog.StateEncoder(3, 1, 0).encode(1, 0.0, np.zeros(3), np.zeros(1), np.zeros(0))
    assert protolog.flat_arrays([short, long], state) is None  # same length, other layout
    assert protolog.flat_arrays([short, short[:-3]], state) is None  # cut
