"""Reads a bag `harvest rec export --ros2` wrote with the independent `rosbags` package and
prints, as JSON, per topic: the type, the message count, every header stamp (ns), and the
facts a test checks (image sizes and encodings, joint names, point fields, detections).
rosbags' AnyReader registers the types from the bag's own definitions and refuses a
definition whose RIHS01 hash differs from the one the bag's metadata gives; each message is
then also checked against the Jazzy type store's definition of its type where it has one.

usage: read_bag.py BAG_DIR
"""
import json
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

bag = Path(sys.argv[1])
jazzy = get_typestore(Stores.ROS2_JAZZY)
topics = {}
with AnyReader([bag]) as reader:
    for connection in reader.connections:
        if connection.msgtype in jazzy.fielddefs:
            hash_jazzy = jazzy.hash_rihs01(connection.msgtype)
            if hash_jazzy != connection.digest:
                raise SystemExit(f"{connection.topic}: {connection.digest} != Jazzy {hash_jazzy}")
        topics[connection.topic] = {"type": connection.msgtype, "count": 0, "stamps": [],
                                    "log_times": [], "hash": connection.digest}
    for connection, log_time, raw in reader.messages():
        msg = reader.deserialize(raw, connection.msgtype)
        entry = topics[connection.topic]
        entry["count"] += 1
        entry["log_times"].append(log_time)
        stamp = msg.header.stamp
        entry["stamps"].append(stamp.sec * 10**9 + stamp.nanosec)
        entry["frame_id"] = msg.header.frame_id
        t = connection.msgtype
        if t == "sensor_msgs/msg/Image":
            entry["size"] = [msg.width, msg.height, msg.step, len(msg.data)]
            entry["encoding"] = msg.encoding
        elif t == "sensor_msgs/msg/CameraInfo":
            entry["k"] = [float(v) for v in msg.k]
            entry["d"] = [float(v) for v in msg.d]
        elif t == "sensor_msgs/msg/JointState":
            entry["names"] = list(msg.name)
            entry.setdefault("positions", []).append([float(v) for v in msg.position])
        elif t == "sensor_msgs/msg/PointCloud2":
            entry["fields"] = [f.name for f in msg.fields]
            entry.setdefault("points", []).append(int(msg.width * msg.height))
        elif t == "vision_msgs/msg/Detection3DArray":
            entry.setdefault("detections", []).append([
                {"id": d.id, "class": d.results[0].hypothesis.class_id,
                 "score": float(d.results[0].hypothesis.score),
                 "position": [d.bbox.center.position.x, d.bbox.center.position.y,
                              d.bbox.center.position.z],
                 "size": d.bbox.size.x}
                for d in msg.detections])
meta = (bag / "metadata.yaml").read_text()
print(json.dumps({"topics": topics, "metadata_yaml_has_hash": "type_description_hash" in meta}))
