"""Run on the visitor's host: roslibpy clients of a rosbridge server on another host, one without authenticating and
one with a MAC from the server's secret; what each got, as JSON."""

import argparse
import json
import secrets
import threading
import time

import roslibpy
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from fleet.ros.rosauth import mac_of


def topics(ros: roslibpy.Ros) -> list[str] | str:
    got, done = {}, threading.Event()
    roslibpy.Service(ros, "/rosapi/topics", "rosapi/Topics").call(
        roslibpy.ServiceRequest(), lambda r: (got.update(ok=r["topics"]), done.set()),
        lambda e: (got.update(error=str(e)), done.set()),
    )  # fmt: skip
    done.wait(5)
    return got.get("ok") or got.get("error") or "no answer"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--server")
    parser.add_argument("--me")
    parser.add_argument("--secret")
    args = parser.parse_args()
    out = {}
    ros = roslibpy.Ros(host=args.server, port=9090)
    ros.run(timeout=20)
    out["without"] = topics(ros)
    ros.close()
    with connect(f"ws://{args.server}:9090") as ws:  # the same, raw: the answer, then the connection closed
        ws.send(json.dumps({"op": "subscribe", "topic": "/joint_states"}))
        out["raw_answer"] = json.loads(ws.recv(timeout=5))
        try:
            ws.recv(timeout=5)
            out["raw_closed"] = None
        except ConnectionClosed as exc:
            out["raw_closed"] = exc.rcvd.code if exc.rcvd else -1
    ros = roslibpy.Ros(host=args.server, port=9090)
    now = int(time.time())
    rand = secrets.token_hex(8)
    mac = mac_of(args.secret, args.me, args.server, rand, now, "user", now + 600)
    ros.authenticate(mac, args.me, args.server, rand, now, "user", now + 600)
    ros.run(timeout=20)
    out["with"] = topics(ros)
    ros.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
