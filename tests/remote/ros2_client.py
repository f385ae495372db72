"""An independent ROS 2 peer of the robot's link, as rmw_zenoh (Jazzy) would see it, with none
of harvest's code: the Python `eclipse-zenoh` client for the session, `rosbags` (Jazzy type
store) for CDR and the RIHS01 type hashes.

    ros2_client.py ENDPOINT ROBOT SECONDS

Reads the ROS 2 graph (liveliness tokens under `@ros2_lv/0/**`), listens to `0/<ROBOT>/**` for
SECONDS and decodes every sample by the type its key names, checks the key's type hash against
rosbags' and the 33-byte attachment, then publishes `std_msgs/msg/Bool` true on the robot's
e-stop topic. Prints one JSON report."""

import json
import struct
import sys
import threading
import time

import zenoh
from rosbags.typesys import Stores, get_typestore

JAZZY = get_typestore(Stores.ROS2_JAZZY)


def open_session(endpoint):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    return zenoh.open(conf)


def ros_type(dds_name):
    """`sensor_msgs::msg::dds_::JointState_` -> `sensor_msgs/msg/JointState`."""
    package, _msg, _dds, name = dds_name.split("::")
    return f"{package}/msg/{name.rstrip('_')}"


def graph(session, limit_s):
    """The liveliness tokens of ROS domain 0, once the node's is among them."""
    deadline = time.monotonic() + limit_s
    tokens = []
    while time.monotonic() < deadline:
        tokens = [str(reply.ok.key_expr) for reply in session.liveliness().get("@ros2_lv/0/**", timeout=1.0)
                  if reply.ok is not None]
        if any("/NN/" in token for token in tokens):
            break
        time.sleep(0.2)
    return sorted(tokens)


def main():
    endpoint, robot, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    session = open_session(endpoint)
    report = {"tokens": graph(session, 20.0), "topics": {}, "errors": []}
    lock = threading.Lock()

    def on_sample(sample):
        key = str(sample.key_expr)
        parts = key.split("/")
        # 0/<robot>/<name...>/<dds type>/<hash>
        name = "/" + "/".join(parts[1:-2])
        msgtype = ros_type(parts[-2])
        data = sample.payload.to_bytes()
        with lock:
            topic = report["topics"].setdefault(name, {"type": msgtype, "hash": parts[-1], "count": 0,
                                                       "sequences": []})
            topic["count"] += 1
            if msgtype not in JAZZY.fielddefs:
                topic["decoded"] = False
                return
            try:
                if parts[-1] != JAZZY.hash_rihs01(msgtype):
                    report["errors"].append(f"{name}: hash {parts[-1]} != Jazzy {JAZZY.hash_rihs01(msgtype)}")
                attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
                if len(attachment) != 33 or attachment[16] != 16:
                    report["errors"].append(f"{name}: attachment of {len(attachment)} bytes")
                else:
                    sequence, stamp = struct.unpack_from("<qq", attachment)
                    topic["sequences"].append(sequence)
                    topic["source_timestamp_ns"] = stamp
                message = JAZZY.deserialize_cdr(data, msgtype)
                if msgtype == "sensor_msgs/msg/JointState":
                    topic["last"] = {"name": list(message.name), "position": [float(p) for p in message.position],
                                     "stamp_s": message.header.stamp.sec}
                elif msgtype == "diagnostic_msgs/msg/DiagnosticArray":
                    topic.setdefault("names", [])
                    for status in message.status:
                        if status.name not in topic["names"]:
                            topic["names"].append(status.name)
                elif msgtype == "sensor_msgs/msg/CompressedImage":
                    jpeg = bytes(message.data)
                    topic["format"] = message.format
                    topic["jpeg_ok"] = topic.get("jpeg_ok", 0) + int(jpeg[:2] == b"\xff\xd8" and jpeg[-2:] == b"\xff\xd9")
                elif msgtype == "std_msgs/msg/String":
                    topic["last"] = json.loads(message.data)
            except Exception as error:  # noqa: BLE001 - every failure goes into the report
                report["errors"].append(f"{name}: {error!r}")

    subscriber = session.declare_subscriber(f"0/{robot}/**", on_sample)
    time.sleep(seconds)
    subscriber.undeclare()

    # The e-stop from ROS: std_msgs/msg/Bool true, CDR, on the topic the robot subscribes to.
    estop_type = "std_msgs/msg/Bool"
    estop_key = f"0/{robot}/emergency_stop/std_msgs::msg::dds_::Bool_/{JAZZY.hash_rihs01(estop_type)}"
    Bool = JAZZY.types[estop_type]
    attachment = struct.pack("<qqB", 1, time.time_ns(), 16) + bytes(16)
    session.put(estop_key, bytes(JAZZY.serialize_cdr(Bool(data=True), estop_type)), attachment=attachment)
    time.sleep(1.0)
    for topic in report["topics"].values():
        sequences = topic.pop("sequences")
        topic["sequences_increase"] = all(b > a for a, b in zip(sequences, sequences[1:]))
    session.close()
    print(json.dumps(report))


main()
