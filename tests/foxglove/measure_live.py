"""Figures of a running `harvest foxglove` with one client (docs/benchmarks.md, "Foxglove
bridge"): the bridge's CPU share of one core while this client is subscribed to every channel at
the default rates, and the camera's capture-to-client latency (client receive time minus the
image's capture timestamp, both wall clock on this host).

usage: measure_live.py --url ws://127.0.0.1:8765 --seconds 20 --pid PID_OF_HARVEST_FOXGLOVE
"""

import argparse
import asyncio
import base64
import json
import os
import struct
import sys
import time

import websockets

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from foxglove_proto import message_class, stamp_ns  # noqa: E402


def cpu_seconds(pid):
    """utime + stime of `pid`, s."""
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(values, p):
    values = sorted(values)
    return values[round((len(values) - 1) * p)] if values else float("nan")


async def measure(url, seconds, pid):
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        channels = {}
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            try:
                raw = await asyncio.wait_for(ws.recv(), timeout=1)
            except asyncio.TimeoutError:
                break
            if isinstance(raw, str):
                message = json.loads(raw)
                if message.get("op") == "advertise":
                    for channel in message["channels"]:
                        channels[channel["id"]] = channel
        classes = {}
        subscriptions = []
        for index, channel in enumerate(channels.values()):
            data = base64.b64decode(channel["schema"])
            classes[index + 1] = (channel["topic"], message_class(channel["schemaName"], data))
            subscriptions.append({"id": index + 1, "channelId": channel["id"]})
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        # Let the subscription settle before the window starts.
        settle = time.monotonic() + 2
        while time.monotonic() < settle:
            await asyncio.wait_for(ws.recv(), timeout=5)
        counts = {}
        latencies_ms = []
        received_bytes = 0
        cpu_before = cpu_seconds(pid)
        started = time.monotonic()
        while time.monotonic() - started < seconds:
            raw = await asyncio.wait_for(ws.recv(), timeout=5)
            received_ns = time.time_ns()
            if not isinstance(raw, bytes) or raw[0] != 1:
                continue
            received_bytes += len(raw)
            subscription, _log_time = struct.unpack_from("<IQ", raw, 1)
            topic, cls = classes[subscription]
            counts[topic] = counts.get(topic, 0) + 1
            if topic == "/camera/image":
                image = cls.FromString(raw[13:])
                latencies_ms.append((received_ns - stamp_ns(image.timestamp)) / 1e6)
        elapsed = time.monotonic() - started
        cpu_share = (cpu_seconds(pid) - cpu_before) / elapsed
    return {
        "seconds": round(elapsed, 2),
        "bridge_cpu_percent_of_one_core": round(cpu_share * 100, 1),
        "images_per_s": round(len(latencies_ms) / elapsed, 2),
        "camera_capture_to_client_ms": {
            "p50": round(percentile(latencies_ms, 0.5), 1),
            "p99": round(percentile(latencies_ms, 0.99), 1),
            "n": len(latencies_ms),
        },
        "received_kb_per_s": round(received_bytes / elapsed / 1e3, 1),
        "messages_per_s": {topic: round(n / elapsed, 1) for topic, n in sorted(counts.items())},
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--url", default="ws://127.0.0.1:8765")
    parser.add_argument("--seconds", type=float, default=20)
    parser.add_argument("--pid", type=int, required=True)
    args = parser.parse_args()
    print(json.dumps(asyncio.run(measure(args.url, args.seconds, args.pid)), indent=1))


if __name__ == "__main__":
    main()
