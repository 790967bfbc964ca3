"""Decode a walkrepro log with the public ``mcap`` reader and published decoders only.

Run as ``python tests/decode_without_walkrepro.py LOG`` (also run by tests/test_foxglove.py in
a subprocess). It never imports walkrepro: what it reads is what any third-party tool sees.
Prints one line per topic and exits non-zero on any inconsistency.
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from datetime import datetime, timezone

from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory


class JsonDecoderFactory(McapDecoderFactory):
    """MCAP's ``json`` message encoding (mcap ships no decoder for it: it is just JSON)."""

    def decoder_for(self, message_encoding, schema):  # noqa: ANN001, ANN201
        return json.loads if message_encoding == "json" else None


def main(path: str) -> int:
    assert "walkrepro" not in sys.modules
    counts: Counter[str] = Counter()
    first: dict[str, object] = {}
    stamps: dict[str, int] = {}
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory(), JsonDecoderFactory()])
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}["walkrepro"]
        origin = int(metadata["log_time_origin"])
        for _schema, channel, message, decoded in reader.iter_decoded_messages():
            topic = channel.topic
            counts[topic] += 1
            first.setdefault(topic, decoded)
            stamps.setdefault(topic, message.log_time)
            # Every stamp is the run's UTC start plus the simulated time in the payload.
            t = decoded["t"] if isinstance(decoded, dict) else getattr(decoded, "t", None)
            if t is not None:
                assert abs(message.log_time - origin - round(t * 1e9)) <= 1, topic
            if topic == "/frames":
                # Decodes against Foxglove's published schema, not only the one in the file.
                frames = FrameTransforms.FromString(message.data)
                assert frames.transforms and frames.transforms[0].parent_frame_id == "world"
                stamp = frames.transforms[0].timestamp
                assert stamp.seconds * 10**9 + stamp.nanos == message.log_time
            elif topic == "/scene":
                scene = SceneUpdate.FromString(message.data)
                assert any(e.cubes for e in scene.entities)
    assert metadata["log_format"] == "2", metadata
    utc = datetime.fromtimestamp(origin / 1e9, tz=timezone.utc)
    print(
        f"log_format {metadata['log_format']}, start {utc.isoformat()}, outcome "
        f"{metadata['outcome']}"
    )
    for topic, n in sorted(counts.items()):
        print(
            f"{topic}: {n} messages, first at {datetime.fromtimestamp(stamps[topic] / 1e9, tz=timezone.utc).isoformat()}"
        )
    state = first["/sim/state"]
    assert len(state.qpos) > 7 and state.step == 0
    for topic in (
        "/sim/state",
        "/sim/inputs",
        "/sim/contacts",
        "/sensors",
        "/frames",
        "/scene",
        "/controller/signals",
    ):
        assert counts[topic] > 0, f"no {topic}"
    assert counts["/sim/inputs"] >= counts["/sim/state"] - 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
