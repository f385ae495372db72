"""Reads a harvest recording with the official `mcap` reader and decodes its mapped Foxglove
channels with the schemas stored in the file (tests/foxglove_bridge.rs runs it).

Prints one JSON document: every channel (topic, message encoding, schema name and encoding,
message count), and per mapped topic what its messages decode to (image sizes, annotation
circles, transform pairs, the robot model's entities, vacuum fields).

usage: read_recording.py FILE.mcap
"""

import json
import os
import sys

from mcap.reader import make_reader

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from foxglove_proto import jpeg_size, message_class, stamp_ns  # noqa: E402


def main(path):
    out = {"channels": {}, "images": [], "annotations": 0, "annotation_circles": 0,
           "transform_pairs": [], "model": {}, "vacuum": [], "events": 0, "log_time_order": True,
           "decode_errors": []}
    classes = {}
    pairs = set()
    last_log_time = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            entry = out["channels"].setdefault(channel.topic, {
                "message_encoding": channel.message_encoding,
                "schema_name": schema.name if schema else "",
                "schema_encoding": schema.encoding if schema else "",
                "count": 0,
                "first_log_time": message.log_time,
            })
            entry["count"] += 1
            entry["last_log_time"] = max(entry.get("last_log_time", 0), message.log_time)
            if channel.message_encoding != "protobuf":
                continue
            if channel.topic in last_log_time and message.log_time < last_log_time[channel.topic]:
                out["log_time_order"] = False
            last_log_time[channel.topic] = message.log_time
            if schema.id not in classes:
                classes[schema.id] = message_class(schema.name, schema.data)
            try:
                decoded = classes[schema.id].FromString(message.data)
            except Exception as error:  # noqa: BLE001 - reported, the test fails on it
                out["decode_errors"].append(f"{channel.topic}: {error}")
                continue
            topic = channel.topic
            if topic == "/camera/image":
                width, height = jpeg_size(decoded.data)
                out["images"].append({"width": width, "height": height,
                                      "stamp_ns": stamp_ns(decoded.timestamp),
                                      "log_time": message.log_time})
            elif topic == "/camera/annotations":
                out["annotations"] += 1
                out["annotation_circles"] += len(decoded.circles)
            elif topic == "/tf":
                for transform in decoded.transforms:
                    pairs.add((transform.parent_frame_id, transform.child_frame_id))
            elif topic == "/robot_model" and not out["model"]:
                out["model"] = {e.id: e.frame_id for e in decoded.entities}
            elif topic == "/vacuum" and len(out["vacuum"]) < 20:
                out["vacuum"].append({"pressure_source_mmh2o": decoded.pressure_source_mmh2o,
                                      "valve1_open": decoded.valve1_open})
            elif topic == "/events":
                out["events"] += 1
    out["transform_pairs"] = sorted([list(pair) for pair in pairs])
    print(json.dumps(out))


main(sys.argv[1])
