"""A page of a console, as a browser's script holds it, without a browser: the WebSocket push
connection at /api/live (the `websockets` library, none of harvest's code), for SECONDS.
Prints one JSON object: how many statuses and camera views came, the newest status, and the
first view's header (the pushed view is a little-endian u32 header length, the header as
JSON, then the JPEG) and whether its JPEG is whole (SOI ... EOI).

usage: console_page.py PORT SESSION SECONDS
"""
import asyncio
import json
import struct
import sys
import time

import websockets


async def main(port, session, seconds):
    report = {"statuses": 0, "views": 0, "status": None, "view_header": None, "jpeg_whole": False}
    url = f"ws://127.0.0.1:{port}/api/live?session={session}"
    async with websockets.connect(url, max_size=None) as ws:
        deadline = time.monotonic() + seconds
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            try:
                message = await asyncio.wait_for(ws.recv(), timeout=left)
            except asyncio.TimeoutError:
                break
            if isinstance(message, str):
                value = json.loads(message)
                if value.get("type") == "status":
                    report["statuses"] += 1
                    report["status"] = value
                continue
            (length,) = struct.unpack_from("<I", message, 0)
            header = json.loads(message[4:4 + length])
            jpeg = message[4 + length:]
            report["views"] += 1
            if report["view_header"] is None:
                report["view_header"] = header
                report["jpeg_whole"] = jpeg[:2] == b"\xff\xd8" and jpeg[-2:] == b"\xff\xd9"
    print(json.dumps(report))


if __name__ == "__main__":
    asyncio.run(main(int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])))
