"""Reads an MCAP file with the independent Python readers (the `mcap` package and
`mcap-ros2-support`'s CDR decoder, built from each channel's ros2msg schema) and prints
one JSON object per message: topic, schema name and encoding, message encoding, log time
and the decoded message as plain JSON; then one object per metadata record.

Used by console/tests/interop.rs. Exit status 3 (and a message naming scripts/setup.sh)
when a package is missing."""

import json
import sys

try:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
except ImportError as e:  # pragma: no cover
    print(f"missing Python package ({e}): run bash scripts/setup.sh", file=sys.stderr)
    sys.exit(3)


def plain(v):
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    if isinstance(v, (bytes, bytearray)):
        return list(v)
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    slots = getattr(type(v), "__slots__", None)
    if slots:
        return {k: plain(getattr(v, k)) for k in slots}
    if hasattr(v, "__dict__"):
        return {k: plain(x) for k, x in vars(v).items() if not k.startswith("_")}
    if hasattr(v, "tolist"):
        return v.tolist()
    return str(v)


def main(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            print(
                json.dumps(
                    {
                        "topic": channel.topic,
                        "schema": schema.name,
                        "schema_encoding": schema.encoding,
                        "message_encoding": channel.message_encoding,
                        "log_time": message.log_time,
                        "msg": plain(decoded),
                    }
                )
            )
    with open(path, "rb") as f:
        for m in make_reader(f).iter_metadata():
            print(json.dumps({"metadata": m.name, "values": dict(m.metadata)}))


if __name__ == "__main__":
    main(sys.argv[1])
