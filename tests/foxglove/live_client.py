"""An independent Foxglove client for `harvest foxglove` (tests/foxglove_bridge.rs runs it).

It speaks the WebSocket protocol with the `websockets` package, decodes messages with the
protobuf descriptors from the server's advertisement (`foxglove_proto.py`) and prints one JSON
document of what it saw, for the Rust test to compare with what the stack published. Meanwhile
bad clients (garbage, unknown channel ids, a slow reader that disconnects mid-frame, a client
offering only an unsupported subprotocol) connect to the same server.

usage: live_client.py --url ws://127.0.0.1:PORT --seconds N
"""

import argparse
import asyncio
import base64
import json
import os
import socket
import struct
import sys
import time

import websockets

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from foxglove_proto import jpeg_size, message_class, stamp_ns  # noqa: E402

SUBPROTOCOL = "foxglove.sdk.v1"
WANTED = [
    "/camera/image", "/camera/calibration", "/camera/annotations", "/apples/detected",
    "/robot_model", "/tf", "/arm1/joints", "/arm2/joints", "/vacuum", "/events",
]


def compose(a, b):
    """(R, t) of a then b: a_from_c = a_from_b * b_from_c."""
    ra, ta = a
    rb, tb = b
    r = [[sum(ra[i][k] * rb[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    t = [sum(ra[i][k] * tb[k] for k in range(3)) + ta[i] for i in range(3)]
    return r, t


def rigid(transform):
    q = transform.rotation
    x, y, z, w = q.x, q.y, q.z, q.w
    r = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    v = transform.translation
    return r, [v.x, v.y, v.z]


class Seen:
    def __init__(self):
        self.counts = {}
        self.images = []
        self.calibration = None
        self.annotations = []
        self.detected = []
        self.arm_tips = []
        self.joints = {}
        self.model = None
        self.vacuum = []
        self.events = []
        self.frames = set()

    def take(self, topic, message, received_ns):
        self.counts[topic] = self.counts.get(topic, 0) + 1
        if topic == "/camera/image":
            width, height = jpeg_size(message.data)
            self.images.append({
                "stamp_ns": stamp_ns(message.timestamp), "received_ns": received_ns,
                "width": width, "height": height, "bytes": len(message.data),
                "format": message.format, "frame_id": message.frame_id,
            })
        elif topic == "/camera/calibration" and self.calibration is None:
            self.calibration = {"width": message.width, "height": message.height,
                                "K": list(message.K), "frame_id": message.frame_id}
        elif topic == "/camera/annotations" and len(self.annotations) < 400:
            meta = {kv.key: kv.value for kv in message.metadata}
            self.annotations.append({
                "stamp_ns": stamp_ns(message.timestamp),
                "source_frame_seq": int(meta.get("source_frame_seq", -1)),
                "circles": [
                    {"x": c.position.x, "y": c.position.y, "diameter": c.diameter,
                     "apple_id": int({kv.key: kv.value for kv in c.metadata}["apple_id"])}
                    for c in message.circles
                ],
                "texts": [t.text for t in message.texts],
            })
        elif topic == "/apples/detected" and len(self.detected) < 400:
            self.detected.append({
                "deletions": len(message.deletions),
                "entities": [
                    {"id": e.id, "frame_id": e.frame_id, "stamp_ns": stamp_ns(e.timestamp),
                     "position": [e.spheres[0].pose.position.x, e.spheres[0].pose.position.y,
                                  e.spheres[0].pose.position.z],
                     "diameter": e.spheres[0].size.x}
                    for e in message.entities
                ],
            })
        elif topic == "/tf":
            for t in message.transforms:
                self.frames.add((t.parent_frame_id, t.child_frame_id))
            children = [t.child_frame_id for t in message.transforms]
            if len(message.transforms) == 4 and children[-1].endswith("_end_effector") \
                    and len(self.arm_tips) < 600:
                total = ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0, 0, 0])
                for t in message.transforms:
                    total = compose(total, rigid(t))
                self.arm_tips.append({
                    "arm": children[-1].split("_")[0],
                    "stamp_ns": stamp_ns(message.transforms[0].timestamp),
                    "tip": total[1],
                })
        elif topic in ("/arm1/joints", "/arm2/joints"):
            entries = self.joints.setdefault(topic, [])
            if len(entries) < 600:
                entries.append({
                    "stamp_ns": stamp_ns(message.timestamp),
                    "names": [j.name for j in message.joints],
                    "position": [j.position for j in message.joints],
                })
        elif topic == "/robot_model" and self.model is None:
            self.model = {e.id: e.frame_id for e in message.entities}
        elif topic == "/vacuum" and len(self.vacuum) < 50:
            self.vacuum.append({"pressure_arm1_mmh2o": message.pressure_arm1_mmh2o,
                                "pressure_source_mmh2o": message.pressure_source_mmh2o,
                                "arm1_attachment_name": message.arm1_attachment_name})
        elif topic == "/events" and len(self.events) < 200:
            self.events.append({"name": message.name, "level": message.level,
                                "message": message.message})


async def good_client(url, seconds, report):
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        report["negotiated_subprotocol"] = ws.subprotocol
        channels = {}
        server_info = None
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not all(
                topic in {c["topic"] for c in channels.values()} for topic in WANTED):
            raw = await asyncio.wait_for(ws.recv(), timeout=10)
            if isinstance(raw, bytes):
                continue
            message = json.loads(raw)
            if message.get("op") == "serverInfo":
                server_info = message
            elif message.get("op") == "advertise":
                for channel in message["channels"]:
                    channels[channel["id"]] = channel
        report["server_name"] = (server_info or {}).get("name")
        report["advertised"] = sorted(
            [{"topic": c["topic"], "encoding": c["encoding"], "schemaName": c["schemaName"],
              "schemaEncoding": c.get("schemaEncoding")} for c in channels.values()],
            key=lambda c: c["topic"])
        classes = {}
        subscriptions = []
        for index, channel in enumerate(channels.values()):
            data = base64.b64decode(channel["schema"])
            classes[index + 1] = (channel["topic"], message_class(channel["schemaName"], data))
            subscriptions.append({"id": index + 1, "channelId": channel["id"]})
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        seen = Seen()
        started = time.monotonic()
        bad_done_at = None
        images_after_bad = 0
        while time.monotonic() - started < seconds:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=2)
            except asyncio.TimeoutError:
                continue
            received_ns = time.time_ns()
            if not isinstance(raw, bytes):
                continue
            if raw[0] != 1:
                continue
            subscription, _log_time = struct.unpack_from("<IQ", raw, 1)
            topic, cls = classes[subscription]
            seen.take(topic, cls.FromString(raw[13:]), received_ns)
            if report.get("bad_clients_done") and bad_done_at is None:
                bad_done_at = time.monotonic()
            if bad_done_at is not None and topic == "/camera/image":
                images_after_bad += 1
        report["counts"] = seen.counts
        report["images"] = seen.images
        report["calibration"] = seen.calibration
        report["annotations"] = seen.annotations
        report["detected"] = seen.detected
        report["arm_tips"] = seen.arm_tips
        report["joints"] = seen.joints
        report["model"] = seen.model
        report["vacuum"] = seen.vacuum
        report["events"] = seen.events
        report["transform_pairs"] = sorted([list(pair) for pair in seen.frames])
        report["images_after_bad_clients"] = images_after_bad


async def old_protocol_client(url, report):
    """Offers only the pre-SDK subprotocol: the server must refuse the handshake."""
    try:
        async with websockets.connect(url, subprotocols=["foxglove.websocket.v1"]):
            report["old_protocol"] = "accepted"
    except websockets.exceptions.InvalidStatus as error:
        report["old_protocol"] = f"refused {error.response.status_code}"
    except Exception as error:  # noqa: BLE001 - any refusal is what we expect
        report["old_protocol"] = f"refused {type(error).__name__}"


async def garbage_client(url, report):
    """Garbage text and binary, unknown ops, unknown channel and subscription ids."""
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None) as ws:
        await ws.send("{this is not json")
        await ws.send(b"\x99\x00\x01garbage")
        await ws.send(json.dumps({"op": "no-such-op"}))
        await ws.send(json.dumps({"op": "subscribe",
                                  "subscriptions": [{"id": 77, "channelId": 987654}]}))
        await ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [4242]}))
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": "nope"}))
        statuses = []
        end = time.monotonic() + 2
        while time.monotonic() < end:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=0.5)
            except asyncio.TimeoutError:
                continue
            if isinstance(raw, str):
                message = json.loads(raw)
                if message.get("op") == "status":
                    statuses.append(message.get("message", ""))
        report["garbage_statuses"] = len(statuses)


def ws_frame(payload, opcode):
    """One masked client frame."""
    mask = os.urandom(4)
    header = bytes([0x80 | opcode])
    length = len(payload)
    if length < 126:
        header += bytes([0x80 | length])
    elif length < 65536:
        header += bytes([0x80 | 126]) + struct.pack(">H", length)
    else:
        header += bytes([0x80 | 127]) + struct.pack(">Q", length)
    masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    return header + mask + masked


def slow_then_cut_client(host, port, seconds, report):
    """A raw-socket client: subscribes to every channel, then reads nothing for `seconds` (a slow
    client the server must drop messages for), then sends half a frame and closes."""
    sock = socket.create_connection((host, port), timeout=5)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((
        f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
        f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n").encode())
    response = b""
    while b"\r\n\r\n" not in response:
        response += sock.recv(4096)
    report["raw_handshake"] = response.split(b"\r\n")[0].decode()
    subscriptions = [{"id": index + 1, "channelId": index + 1} for index in range(40)]
    sock.sendall(ws_frame(json.dumps({"op": "subscribe", "subscriptions": subscriptions}).encode(), 1))
    time.sleep(seconds)
    frame = ws_frame(b"x" * 1000, 2)
    sock.sendall(frame[:20])
    sock.close()


async def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", required=True)
    parser.add_argument("--seconds", type=float, default=12)
    args = parser.parse_args()
    host, port = args.url.split("//")[1].split(":")
    report = {}
    good = asyncio.create_task(good_client(args.url, args.seconds, report))
    await asyncio.sleep(2)
    await old_protocol_client(args.url, report)
    await garbage_client(args.url, report)
    await asyncio.to_thread(slow_then_cut_client, host, int(port), 3.0, report)
    report["bad_clients_done"] = True
    await good
    print(json.dumps(report))


asyncio.run(main())
