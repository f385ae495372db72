"""An independent station for the remote link: the Python `eclipse-zenoh` client (pip), with
none of harvest's code. It decodes what the robot publishes (JSON states, the fleet summary,
the camera JPEG and its attachment) and sends operator queries, and prints one JSON report.

    station_client.py watch ENDPOINT ROBOT SECONDS [--user U --password P]
    station_client.py query ENDPOINT KEY PAYLOAD [--repeat N] [--user U --password P]

PAYLOAD is JSON text, `@empty`, or `@oversized` (4 KiB of spaces)."""

import json
import sys
import threading
import time

import zenoh


def open_session(endpoint, user, password):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("scouting/gossip/enabled", "false")
    if user is not None:
        conf.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
    return zenoh.open(conf)


def wait_for_robot(session, robot, limit_s):
    """True once the robot's liveliness token is seen."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        for reply in session.liveliness().get(f"harvest/v1/{robot}/alive", timeout=1.0):
            if reply.ok is not None:
                return True
        time.sleep(0.2)
    return False


def is_jpeg(data):
    return len(data) > 4 and data[:2] == b"\xff\xd8" and data[-2:] == b"\xff\xd9"


def watch(session, robot, seconds):
    lock = threading.Lock()
    counts = {}
    first = {}
    last = {}
    camera = {"images": 0, "bytes": 0, "jpeg_ok": 0, "attachments": []}
    prefix = f"harvest/v1/{robot}/"

    def on_sample(sample):
        key = str(sample.key_expr)
        suffix = key[len(prefix):]
        data = sample.payload.to_bytes()
        now = time.monotonic()
        with lock:
            counts[suffix] = counts.get(suffix, 0) + 1
            first.setdefault(suffix, now)
            last[suffix] = now
            if suffix == "camera/jpeg":
                camera["images"] += 1
                camera["bytes"] += len(data)
                camera["jpeg_ok"] += 1 if is_jpeg(data) else 0
                if sample.attachment is not None:
                    camera["attachments"].append(json.loads(sample.attachment.to_bytes()))
            else:
                try:
                    decoded = json.loads(data)
                except ValueError:
                    decoded = {"undecodable": len(data)}
                last[suffix + "#value"] = decoded

    subscriber = session.declare_subscriber(prefix + "**", on_sample)
    start = time.monotonic()
    time.sleep(seconds)
    subscriber.undeclare()
    elapsed = time.monotonic() - start
    with lock:
        values = {k[: -len("#value")]: v for k, v in last.items() if k.endswith("#value")}
        return {
            "elapsed_s": elapsed,
            "counts": counts,
            "rates_hz": {k: counts[k] / elapsed for k in counts},
            "values": values,
            "camera": camera,
        }


def query(session, key, payload, repeat):
    if payload == "@empty":
        data = b""
    elif payload == "@oversized":
        data = b" " * 4096
    else:
        data = payload.encode()
    answers = []
    for _ in range(repeat):
        replies = []
        for reply in session.get(key, payload=data, timeout=3.0):
            if reply.ok is not None:
                replies.append(json.loads(reply.ok.payload.to_bytes()))
            else:
                replies.append({"error": reply.err.payload.to_bytes().decode(errors="replace")})
        answers.append(replies)
    return {"answers": answers}


def main():
    args = sys.argv[1:]
    user = password = None
    repeat = 1
    if "--user" in args:
        i = args.index("--user")
        user = args[i + 1]
        del args[i : i + 2]
    if "--password" in args:
        i = args.index("--password")
        password = args[i + 1]
        del args[i : i + 2]
    if "--repeat" in args:
        i = args.index("--repeat")
        repeat = int(args[i + 1])
        del args[i : i + 2]
    mode, endpoint = args[0], args[1]
    session = open_session(endpoint, user, password)
    if mode == "watch":
        robot, seconds = args[2], float(args[3])
        seen = wait_for_robot(session, robot, 15.0)
        report = {"robot_seen": seen}
        if seen:
            report.update(watch(session, robot, seconds))
    else:
        key, payload = args[2], args[3]
        robot = key.split("/")[2]
        seen = wait_for_robot(session, robot, 8.0)
        report = {"robot_seen": seen}
        report.update(query(session, key, payload, repeat))
    session.close()
    print(json.dumps(report))


if __name__ == "__main__":
    main()
