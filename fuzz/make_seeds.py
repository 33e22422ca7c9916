#!/usr/bin/env python3
"""Write the replay fuzz seeds from three tiny gripsim runs.

    python3 fuzz/make_seeds.py            # from the repository root, after cargo build --release

Needs the `mcap` Python package (the tests install it into .venv: .venv/bin/python works).
Writes fuzz/seeds/replay_mcap/*.mcap (as gripsim writes them, and the same messages
unchunked and uncompressed) and fuzz/seeds/replay_messages/*.txt (the line form that the
replay_messages target reads: `<kind> <json body>`), and the seeds of the 3D reader,
fuzz/seeds/replay_mcap3d/*.mcap (a 3-step two-finger run as written, and plain: unchunked,
uncompressed, without /scene). `main3d()` alone writes the 3D seeds.
"""
import os
import subprocess
import sys

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "target", "release", "gripsim")
RAW = os.path.join(ROOT, "fuzz", "seeds", "replay_mcap")
MSG = os.path.join(ROOT, "fuzz", "seeds", "replay_messages")
RUNS = {
    # a point mass landing on a plane (a spike, contact held)
    "ball": ["recordings/golden/point-mass-plane-dt1e-4.toml",
             "--set", "particle.0.position=[0.0, 0.00002]", "--set", "solve.t_end=0.0025"],
    # a free rod landing on a plane
    "rod": ["fuzz/seeds/scenario/rod-on-plane.toml", "--set", "solve.t_end=0.0025",
            "--set", "rod.0.nodes=3",
            "--set", "rod.0.shape.start=[0.0, 0.00002]", "--set", "rod.0.shape.end=[0.02, 0.00002]"],
    # a static solve
    "static": ["scenarios/cantilever-tip-load.toml", "--set", "rod.0.nodes=5",
               "--set", "rod.0.loads.0.node=4"],
}
RAW3 = os.path.join(ROOT, "fuzz", "seeds", "replay_mcap3d")
RUN3 = ["scenarios/3d-two-finger-sphere.toml", "--set", "solve.t_end=0.0003"]
KIND = {"/sim/meta": "meta", "/sim/step": "step", "/sim/contact": "contact",
        "/sim/event": "event", "/sim/iteration": "iteration"}


def main():
    os.makedirs(RAW, exist_ok=True)
    os.makedirs(MSG, exist_ok=True)
    for name, args in RUNS.items():
        path = os.path.join(RAW, f"{name}.mcap")
        subprocess.run([BIN, "run", *args, "--mcap", path, "-q"], cwd=ROOT, check=True)
        with open(path, "rb") as f:
            reader = make_reader(f)
            metadata = list(reader.iter_metadata())
            messages = list(reader.iter_messages())
            summary = reader.get_summary()
        # The same run unchunked and uncompressed, without /scene and with empty schema texts
        # (replay checks schema names only): small, and mutations reach the JSON.
        with open(os.path.join(RAW, f"{name}-plain.mcap"), "wb") as f:
            w = Writer(f, compression=CompressionType.NONE, use_chunking=False)
            w.start("", "make_seeds.py")
            # Every channel, also those without a message (a static run has no contact).
            schemas, channels = {}, {}
            for channel in summary.channels.values():
                if channel.topic == "/scene":
                    continue
                schema = summary.schemas[channel.schema_id]
                if schema.id not in schemas:
                    schemas[schema.id] = w.register_schema(schema.name, schema.encoding, b"")
                channels[channel.id] = w.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id])
            for schema, channel, message in messages:
                if channel.topic == "/scene":
                    continue
                w.add_message(channels[channel.id], message.log_time, message.data,
                              message.publish_time, message.sequence)
            for m in metadata:
                w.add_metadata(m.name, m.metadata)
            w.finish()
        lines = []
        for m in metadata:
            if m.name == "gripsim":
                lines.append(f"version {m.metadata.get('format_version', '')}")
        for _, channel, message in messages:
            kind = KIND.get(channel.topic)
            if kind:
                lines.append(f"{kind} {message.data.decode()}")
        for m in metadata:
            if m.name == "gripsim.run_end":
                lines.append("end " + ",".join(f"{k}={v}" for k, v in m.metadata.items()))
        with open(os.path.join(MSG, f"{name}.txt"), "w") as f:
            f.write("\n".join(lines) + "\n")
    # Only one seed as gripsim writes it (zstd chunks): the container paths.
    for name in RUNS:
        if name != "ball":
            os.remove(os.path.join(RAW, f"{name}.mcap"))
    for d in (RAW, MSG):
        for f in sorted(os.listdir(d)):
            print(f"{os.path.join(d, f)}: {os.path.getsize(os.path.join(d, f))} bytes")
    main3d()


def plain(path, out, skip):
    """The messages of `path` unchunked and uncompressed, without the topics in `skip`."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        metadata = list(reader.iter_metadata())
        messages = list(reader.iter_messages())
        summary = reader.get_summary()
    with open(out, "wb") as f:
        w = Writer(f, compression=CompressionType.NONE, use_chunking=False)
        w.start("", "make_seeds.py")
        schemas, channels = {}, {}
        for channel in summary.channels.values():
            if channel.topic in skip:
                continue
            schema = summary.schemas[channel.schema_id]
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, b"")
            channels[channel.id] = w.register_channel(
                channel.topic, channel.message_encoding, schemas[schema.id])
        for schema, channel, message in messages:
            if channel.topic in skip:
                continue
            w.add_message(channels[channel.id], message.log_time, message.data,
                          message.publish_time, message.sequence)
        for m in metadata:
            w.add_metadata(m.name, m.metadata)
        w.finish()


def main3d():
    os.makedirs(RAW3, exist_ok=True)
    path = os.path.join(RAW3, "two-finger.mcap")
    subprocess.run([BIN, "run", *RUN3, "--mcap", path, "-q"], cwd=ROOT, check=True)
    plain(path, os.path.join(RAW3, "two-finger-plain.mcap"), {"/scene", "/scene/static"})
    for f in sorted(os.listdir(RAW3)):
        print(f"{os.path.join(RAW3, f)}: {os.path.getsize(os.path.join(RAW3, f))} bytes")


if __name__ == "__main__":
    sys.exit(main())
