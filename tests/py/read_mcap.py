#!/usr/bin/env python3
"""An independent reader of gripsim MCAP recordings (the `mcap` package from PyPI).

Usage: read_mcap.py FILE.mcap

Reads every record in file order with CRC validation (chunk CRCs and, for a finished file,
the data section CRC), decodes every message: JSON channels as JSON, validating samples of
each against the JSON schema the file carries; protobuf channels (/sim/step, /sim/iteration
of format 2) with Google's `protobuf` library from the FileDescriptorSet the file carries
(through `mcap-protobuf-support`'s decoder factory). Prints a JSON report on stdout:

  topics        {topic: {schema, schema_encoding, message_encoding, messages}}
  summary       whether the summary section (with statistics) and the footer are there,
                and the statistics' message count
  metadata      {name: {key: value}} of the Metadata records
  steps         step numbers of the /sim/step messages, in order
  last_event    the last /sim/event message
  log_time_monotone   whether log times never decrease in file order
  validated     how many messages were validated against their schema (JSON) or decoded
                by the protobuf library (protobuf)
  step_samples  the first /sim/step messages and every 250th after, as the protobuf (or
                JSON) library decoded them: step, t, dt and per rod q, reaction_norm,
                in_contact, gap (null for no obstacle); contacts: rod, node, obstacle, body,
                first and last node of an arc (-1 for none), normal force and the
                compliant contact's indentation, half-width, peak pressure, bruise threshold
                and bruise half-width
  scene_samples the first /scene messages and every 250th after (format 3: protobuf
                foxglove.SceneUpdate, decoded by Google's library): index (the message's
                number on the topic = its step), and per entity its id, the points of its
                first line, its spheres' centres, the number of arrows, texts and cubes and
                the point counts of its triangle lists (3D format 3: the same protobuf)
  node_samples  the first /scene/nodes messages and every 250th after (format 4: protobuf
                foxglove.PointCloud, decoded by Google's library; its packed `data` unpacked
                with `struct` through the message's own `fields` and `point_stride`): index,
                frame_id, and per point {x, y, z, red, green, blue, alpha}
  fingerprints  format 4: {steps, checked, matched}: steps carrying a fingerprint, and of the
                gripsim.Step64 (f64) ones how many were recomputed here (FNV-1a 64 over the
                little-endian f64 bytes of every rod's q then u, then every body's position,
                angle, velocity, angular velocity) and how many matched
  scene_static  the /scene/static message's entity ids, line counts and triangle lists' point
                counts
  last_step3    (3D runs, schema gripsim.Step3) the last /sim/step as decoded: per rod x (x, y, z
                interleaved), theta, twist, m1; bodies' shape, position, rotation; contacts'
                rod, node, shape, normal force, reaction, friction, stuck. The same shape is in
                step_samples; meta3 holds the rods' names, the shapes and the format_version
                of /sim/meta
  error         null, or why reading stopped early (a file cut short by a crash)

A file cut short (no summary, last chunk half written) is read up to its last complete
record; `error` then says where reading stopped.
"""

import json
import math
import struct
import sys

import jsonschema
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema, Statistics
from mcap.stream_reader import StreamReader
from mcap_protobuf.decoder import DecoderFactory


def finite(xs):
    return [x if math.isfinite(x) else None for x in xs]


def step_sample(msg):
    """What the report shows of a /sim/step message (a protobuf message or a JSON dict)."""
    get = (lambda m, k: m[k]) if isinstance(msg, dict) else getattr
    rods = []
    for r in get(msg, "rods"):
        gap = [math.inf if g is None else g for g in get(r, "gap")]
        rods.append(
            {
                "q": list(get(r, "q")),
                "reaction_norm": list(get(r, "reaction_norm")),
                "in_contact": list(get(r, "in_contact")),
                "gap": finite(gap),
            }
        )
    # A file written before a field existed has no such field: None.
    field = (lambda m, k: m.get(k)) if isinstance(msg, dict) else (lambda m, k: getattr(m, k, None))
    def value(c, k):
        v = field(c, k)
        return int(v) if k in INDEX_FIELDS and v is not None else v

    contacts = [{k: value(c, k) for k in CONTACT_FIELDS} for c in (field(msg, "contacts") or [])]
    return {
        "step": int(get(msg, "step")),
        "t": get(msg, "t"),
        "dt": get(msg, "dt"),
        "rods": rods,
        "contacts": contacts,
        "fingerprint": None if isinstance(msg, dict) else int(getattr(msg, "fingerprint", 0)),
    }


FNV_OFFSET, FNV_PRIME = 0xCBF29CE484222325, 0x100000001B3


def fingerprint(msg):
    """FNV-1a 64 of the exact f64 state of a gripsim.Step64 message (docs/recording-format.md)."""
    h = FNV_OFFSET
    xs = []
    for r in msg.rods:
        xs += list(r.q) + list(r.u)
    for b in msg.bodies:
        xs += list(b.position) + [b.angle] + list(b.velocity) + [b.angular_velocity]
    for byte in struct.pack("<%dd" % len(xs), *xs):
        h = ((h ^ byte) * FNV_PRIME) & 0xFFFFFFFFFFFFFFFF
    return h


# PackedElementField.NumericType -> struct format
NUMERIC = {1: "B", 2: "b", 3: "H", 4: "h", 5: "I", 6: "i", 7: "f", 8: "d"}


def node_sample(msg, index):
    """What the report shows of a /scene/nodes foxglove.PointCloud."""
    points = []
    data = bytes(msg.data)
    for start in range(0, len(data), msg.point_stride):
        points.append(
            {
                f.name: struct.unpack_from("<" + NUMERIC[f.type], data, start + f.offset)[0]
                for f in msg.fields
            }
        )
    return {"index": index, "frame_id": msg.frame_id, "stride": msg.point_stride, "points": points}


def xyz(v):
    return [v.x, v.y, v.z]


def scene_sample(msg, index):
    """What the report shows of a protobuf /scene message."""
    entities = []
    for e in msg.entities:
        entities.append(
            {
                "id": e.id,
                "line_points": [xyz(p) for p in e.lines[0].points] if e.lines else [],
                "spheres": [xyz(s.pose.position) for s in e.spheres],
                "arrows": len(e.arrows),
                "texts": [t.text for t in e.texts],
                "cubes": len(e.cubes),
                "triangles": [len(t.points) for t in e.triangles],
            }
        )
    return {"index": index, "entities": entities}


def step3_sample(msg):
    """What the report shows of a 3D run's /sim/step message (gripsim.Step3, protobuf)."""
    return {
        "step": int(msg.step),
        "t": msg.t,
        "dt": msg.dt,
        "rods": [
            {"x": list(r.x), "theta": list(r.theta), "twist": list(r.twist), "m1": list(r.m1)}
            for r in msg.rods
        ],
        "bodies": [
            {"shape": int(b.shape), "position": list(b.position), "rotation": list(b.rotation)}
            for b in msg.bodies
        ],
        "contacts": [
            {
                "rod": int(c.rod),
                "node": int(c.node),
                "shape": int(c.shape),
                "normal_force": c.normal_force,
                "reaction": list(c.reaction),
                "friction": list(c.friction),
                "stuck": c.stuck,
            }
            for c in msg.contacts
        ],
    }


# What the report shows of each active contact of a sampled step.
# The contact's indices (protobuf integers; -1 for none, as in the file).
INDEX_FIELDS = {"rod", "node", "obstacle", "body", "first", "last"}

CONTACT_FIELDS = [
    "rod",
    "node",
    "obstacle",
    "body",
    "first",
    "last",
    "normal_force",
    "indentation",
    "half_width",
    "peak_pressure",
    "bruise_pressure",
    "bruise_half_width",
]


def main(path):
    schemas, channels, validators = {}, {}, {}
    topics, metadata, steps = {}, {}, []
    report = {"summary": {"statistics": False, "footer": False, "data_end": False}}
    last_event, last_time, monotone = None, -1, True
    seen, validated, error = {}, 0, None
    protobuf, decoders, samples = DecoderFactory(), {}, []
    scene_samples, scene_static = [], None
    node_samples, prints = [], {"steps": 0, "checked": 0, "matched": 0}
    last_step3 = None
    with open(path, "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                    schema = schemas.get(record.schema_id)
                    topics.setdefault(
                        record.topic,
                        {
                            "schema": schema.name if schema else None,
                            "schema_encoding": schema.encoding if schema else None,
                            "message_encoding": record.message_encoding,
                            "messages": 0,
                        },
                    )
                    if schema and schema.encoding == "jsonschema" and record.id not in validators:
                        validators[record.id] = jsonschema.Draft202012Validator(json.loads(schema.data))
                    if record.message_encoding == "protobuf":
                        decoders[record.id] = protobuf.decoder_for(record.message_encoding, schema)
                elif isinstance(record, Message):
                    channel = channels[record.channel_id]
                    topic = channel.topic
                    topics[topic]["messages"] += 1
                    if record.log_time < last_time:
                        monotone = False
                    last_time = record.log_time
                    n = seen.get(topic, 0)
                    seen[topic] = n + 1
                    if record.channel_id in decoders:
                        msg = decoders[record.channel_id](record.data)
                        validated += 1
                    else:
                        msg = json.loads(record.data)
                        # Validate the first messages of each channel and a sample after.
                        if n < 20 or n % 250 == 0:
                            validators[record.channel_id].validate(msg)
                            validated += 1
                    schema = schemas.get(channel.schema_id)
                    if topic == "/sim/step" and schema is not None and schema.name == "gripsim.Step3":
                        # A 3D run (dimension = 3): its own step message.
                        steps.append(int(msg.step))
                        last_step3 = step3_sample(msg)
                        if n < 20 or n % 250 == 0:
                            samples.append(last_step3)
                    elif topic == "/sim/step":
                        step = msg["step"] if isinstance(msg, dict) else msg.step
                        steps.append(int(step))
                        if n < 20 or n % 250 == 0:
                            samples.append(step_sample(msg))
                        if not isinstance(msg, dict) and msg.fingerprint:
                            prints["steps"] += 1
                            if schema.name == "gripsim.Step64":
                                prints["checked"] += 1
                                prints["matched"] += fingerprint(msg) == msg.fingerprint
                    elif topic == "/scene/nodes":
                        if n < 20 or n % 250 == 0:
                            node_samples.append(node_sample(msg, n))
                    elif topic == "/sim/event":
                        last_event = msg
                    elif topic == "/scene" and not isinstance(msg, dict):
                        if n < 20 or n % 250 == 0:
                            scene_samples.append(scene_sample(msg, n))
                    elif topic == "/scene/static" and not isinstance(msg, dict):
                        scene_static = [
                            {"id": e.id, "lines": len(e.lines), "triangles": [len(t.points) for t in e.triangles]}
                            for e in msg.entities
                        ]
                    elif topic == "/sim/meta" and isinstance(msg, dict) and msg.get("dimension") == 3:
                        report["meta3"] = {
                            "rods": [r["name"] for r in msg["rods"]],
                            "shapes": msg["shapes"],
                            "format_version": msg["format_version"],
                        }
                elif isinstance(record, Metadata):
                    metadata[record.name] = dict(record.metadata)
                elif isinstance(record, Statistics):
                    report["summary"]["statistics"] = True
                    report["summary"]["message_count"] = record.message_count
                elif isinstance(record, DataEnd):
                    report["summary"]["data_end"] = True
                elif isinstance(record, Footer):
                    report["summary"]["footer"] = True
        except Exception as e:  # a file cut short: report where reading stopped
            error = f"{type(e).__name__}: {e}"
    if report["summary"]["footer"]:
        # The indexed path too: the summary must lead to the same messages.
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            report["summary"]["chunk_indexes"] = len(summary.chunk_indexes)
            report["summary"]["indexed_messages"] = sum(1 for _ in reader.iter_messages())
    report.update(
        topics=topics,
        metadata=metadata,
        steps=steps,
        last_event=last_event,
        log_time_monotone=monotone,
        validated=validated,
        step_samples=samples,
        scene_samples=scene_samples,
        node_samples=node_samples,
        fingerprints=prints,
        scene_static=scene_static,
        last_step3=last_step3,
        error=error,
    )
    json.dump(report, sys.stdout)
    print()


if __name__ == "__main__":
    main(sys.argv[1])
