"""Tests of walkrepro.log.protolog: the numeric topics' protobuf schemas and wire encoders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from walkrepro.log import protolog

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


def _state_encoder(nq: int, nv: int, na: int) -> protolog.RowEncoder:
    return protolog.RowEncoder(
        [(1, protolog.COUNT, 1), (2, protolog.SCALAR, 1), (3, protolog.ARRAY, nq),
         (4, protolog.ARRAY, nv), (5, protolog.ARRAY, na)]
    )  # fmt: skip


def _state(encoder: protolog.RowEncoder, step: int, t: float, *arrays: np.ndarray) -> bytes:
    return encoder.encode_one(np.concatenate(([step, t], *arrays)))


def test_state_rows_are_protobufs_encoding_of_the_same_message() -> None:
    """A SimState written from a row parses to the values given, bit for bit, and protobuf's
    own serialization of those values is the same bytes."""
    cls = _classes()["walkrepro.SimState"]
    qpos = np.array([0.1, -0.0, 5e-324, math.nan, 1e300])
    qvel, act = np.arange(4.0), np.zeros(0)
    data = _state(_state_encoder(5, 4, 0), 12345, 0.0005, qpos, qvel, act)
    message = cls.FromString(data)
    assert message.step == 12345 and message.t == 0.0005
    assert _bits(message.qpos) == qpos.tobytes() and _bits(message.qvel) == qvel.tobytes()
    assert list(message.act) == []
    reference = cls(step=12345, t=0.0005, qpos=qpos.tolist(), qvel=qvel.tolist())
    assert data == reference.SerializeToString()


def test_a_batch_is_its_rows_encoded_one_by_one() -> None:
    """RowEncoder.encode of many rows gives each row's message; integers (sfixed64) keep their
    sign and value."""
    encoder = protolog.RowEncoder(
        [(1, protolog.SCALAR, 1), (2, protolog.INTEGER, 1), (3, protolog.ARRAY, 3)]
    )
    rows = np.array([[0.5, -3, 1.0, 2.0, -0.0], [1e-300, 2**40, 0.0, 0.0, 5e-324]])
    batch = encoder.encode(rows)
    assert batch.shape == (2, encoder.size)
    layout = protolog.signals_layout([("k", protolog.INTEGER), ("v", protolog.ARRAY)])
    cls = protolog.message_classes(protolog.file_descriptor_set(signals=layout))
    for row, data in zip(rows, batch, strict=True):
        assert data.tobytes() == encoder.encode_one(row)
        message = cls["walkrepro.Signals"].FromString(data.tobytes())
        assert (message.t, message.k) == (row[0], int(row[1]))
        assert _bits(message.v) == row[2:].tobytes()


def test_step_zero_and_time_zero_are_written_and_read() -> None:
    """Scalars are always on the wire (protobuf parsers read explicit zeros)."""
    cls = _classes()["walkrepro.SimContacts"]
    data = protolog.ContactsEncoder().encode(0, 0.0, {})
    assert data == b"\x09" + bytes(8) + b"\x11" + bytes(8)
    assert cls.FromString(data) == cls()


def test_contacts_keep_wrench_names_and_order() -> None:
    """Repeated Wrench entries keep their names, 6 values and order."""
    wrenches = {"pelvis": np.arange(6.0), "a/much_longer_name" * 8: [0.0, -0.0, 1, 2, 3, 4]}
    decode = protolog.dict_decoder(protolog.file_descriptor_set(), "walkrepro.SimContacts")
    contacts = protolog.ContactsEncoder().encode(3, 0.5, wrenches)
    assert decode(contacts) == {
        "step": 3,
        "t": 0.5,
        "pairs": {name: [float(x) for x in w] for name, w in wrenches.items()},
    }
    assert list(decode(contacts)["pairs"]) == list(wrenches)
    cls = _classes()["walkrepro.SimContacts"]
    assert [(w.name, _bits(w.wrench)) for w in cls.FromString(contacts).pairs] == [
        (name, _bits(w)) for name, w in wrenches.items()
    ]


def test_sensors_layout_follows_the_first_snapshot() -> None:
    """Numbers, arrays and not-provided fields get double, repeated double and NullValue
    fields in the snapshot's order; a row in another column order decodes the same."""
    layout = protolog.sensors_layout(SENSORS)
    assert layout == (("t", "scalar"), ("joint_pos", "array"), ("imu_quat", "array"),
                      ("base_pos", "null"), ("empty", "array"))  # fmt: skip
    schema = protolog.file_descriptor_set(layout)
    cls = protolog.message_classes(schema)["walkrepro.Sensors"]
    assert [f.name for f in cls.DESCRIPTOR.fields] == [key for key, _ in layout]
    assert cls.DESCRIPTOR.fields_by_name["base_pos"].enum_type.full_name == (
        "google.protobuf.NullValue"
    )
    sizes = {"joint_pos": 3, "imu_quat": 4, "empty": 0}
    decode = protolog.dict_decoder(schema, "walkrepro.Sensors")
    want = {"t": 0.25, "joint_pos": [0.1, -0.0, 5e-324], "imu_quat": [1.0, 0.0, 0.0, 0.0],
            "base_pos": None, "empty": []}  # fmt: skip
    for order in ((), ("t", "imu_quat", "empty", "joint_pos")):
        fields = protolog.row_fields(layout, sizes, order)
        keys = order or ("t", "joint_pos", "imu_quat", "empty")
        kinds = dict(layout)
        row = protolog.message_row(SENSORS, [(k, kinds[k], sizes.get(k, 1)) for k in keys])
        decoded = decode(protolog.RowEncoder(fields).encode_one(row))
        assert decoded == want
        assert _bits(decoded["joint_pos"]) == SENSORS["joint_pos"].tobytes()
    with pytest.raises(ValueError, match="not the layout's fields"):
        protolog.row_fields(layout, sizes, ("t", "joint_pos"))


def test_message_rows_of_another_shape_are_refused() -> None:
    """A message whose values differ in kind or size from the layout raises ValueError."""
    fields = [("t", protolog.SCALAR, 1), ("q", protolog.ARRAY, 2)]
    assert protolog.message_row({"t": 1.0, "q": [1, 2]}, fields).tolist() == [1.0, 1.0, 2.0]
    for bad in ({"t": np.zeros(2), "q": [1, 2]}, {"t": 1.0, "q": [1.0]}, {"t": 1.0, "q": None}):
        with pytest.raises(ValueError, match="changed kind"):
            protolog.message_row(bad, fields)
    with pytest.raises(ValueError, match="a sensor field is"):
        protolog.sensors_layout({"flag": True})


def test_varint_matches_protobuf() -> None:
    """Varints (packed-field lengths) as protobuf spells them."""
    for n, spelled in ((0, b"\x00"), (1, b"\x01"), (127, b"\x7f"), (128, b"\x80\x01"),
                       (300, b"\xac\x02")):  # fmt: skip
        assert protolog.varint(n) == spelled


def test_flat_arrays_read_every_message_bit_for_bit() -> None:
    """flat_arrays gives the values of each message (steps as int64, in file order), the same
    as decoding each; not-provided fields are left out; flat_messages gives the dicts."""
    encoder = _state_encoder(3, 2, 0)
    rng = np.random.default_rng(1)
    steps = [0, 5, 127, 128, 300, 2**40, 1]
    qpos = rng.standard_normal((len(steps), 3))
    qpos[0, 0] = -0.0
    raw = [_state(encoder, s, s * 1e-3, q, q[:2]) for s, q in zip(steps, qpos, strict=True)]
    cls = _classes()["walkrepro.SimState"]
    arrays = protolog.flat_arrays(raw, cls.DESCRIPTOR)
    assert arrays is not None
    assert arrays["step"].tolist() == steps
    assert arrays["qpos"].tobytes() == qpos.tobytes() and arrays["act"].shape == (7, 0)
    assert arrays["t"].tolist() == [s * 1e-3 for s in steps]
    decode = protolog.dict_decoder(protolog.file_descriptor_set(), "walkrepro.SimState")
    assert protolog.flat_messages(raw, cls.DESCRIPTOR) == [decode(data) for data in raw]


def test_flat_arrays_refuse_what_does_not_fit() -> None:
    """Sub-messages, ragged arrays and foreign bytes give None (callers decode one by one)."""
    classes = _classes()
    contacts = protolog.ContactsEncoder().encode(1, 0.5, {"a/b": np.zeros(6)})
    assert protolog.flat_arrays([contacts], classes["walkrepro.SimContacts"].DESCRIPTOR) is None
    state = classes["walkrepro.SimState"].DESCRIPTOR
    short = _state(_state_encoder(2, 2, 0), 1, 0.0, np.zeros(2), np.zeros(2))
    long = _state(_state_encoder(3, 1, 0), 1, 0.0, np.zeros(3), np.zeros(1))
    assert protolog.flat_arrays([short, long], state) is None  # same length, other layout
    assert protolog.flat_arrays([short, short[:-3]], state) is None  # cut
