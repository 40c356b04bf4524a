"""`fleet bench foxglove`: what serving a lockstep line to one Foxglove app costs. The sorting line's lockstep runs
without, and with `--foxglove` and one client subscribed to every channel the server advertises (reading all it
sends), in turn; the sim loop's wall time compared, pair by pair. With `--cameras`, both runs render every camera
of the scene (the client then takes the images too).

The client here speaks the protocol's JSON and counts the binary frames (load, not proof: the tests prove the
protocol with Foxglove's own reference client)."""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass

import numpy as np
from websockets.sync.client import connect

from fleet.run.launcher import Launcher, RunOptions

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


@dataclass(frozen=True)
class FoxgloveCostRow:
    variant: str
    loop_wall_seconds: float
    ratio_to_plain: float
    messages: float  # what the client got (binary frames: messages and the server's time)


def _client(launcher: Launcher, got: list[int], stop: threading.Event) -> None:
    """Subscribe to every channel advertised, then read until stopped."""
    try:
        with connect(launcher.server_url("foxglove"), subprotocols=SUBPROTOCOLS) as ws:
            subscribed = 0
            while not stop.is_set():
                try:
                    frame = ws.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, bytes):
                    got[0] += 1
                    continue
                message = json.loads(frame)
                if message.get("op") == "advertise":
                    wanted = []
                    for channel in message["channels"]:
                        subscribed += 1
                        wanted.append({"id": subscribed, "channelId": channel["id"]})
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": wanted}))
    except Exception:  # the run ended under it
        return


def _run(arms: int, seconds: float, served: bool, cameras: bool) -> tuple[float, int]:
    """One lockstep run, served to one Foxglove client or not; the sim loop's wall seconds, what the client got."""
    options = RunOptions(
        "sorting_line",
        arms=arms,
        duration_s=seconds,
        foxglove_port=0 if served else None,
        cameras="all" if cameras else None,
    )
    got, stop = [0], threading.Event()
    with Launcher(options) as launcher:
        client = threading.Thread(target=_client, args=(launcher, got, stop), daemon=True)
        if served:
            client.start()
        summary = launcher.run()
        stop.set()
        if served:
            client.join(5)
    return float(summary["loop_wall_seconds"]), got[0]


def bench_foxglove_cost(
    arms: int = 4, seconds: float = 60.0, repeats: int = 3, cameras: bool = False
) -> list[FoxgloveCostRow]:
    """Plain and served runs in turn, `repeats` pairs; medians, and the median of the pairs' ratios."""
    plain, served, got = [], [], []
    for _ in range(repeats):
        plain.append(_run(arms, seconds, False, cameras)[0])
        wall, messages = _run(arms, seconds, True, cameras)
        served.append(wall)
        got.append(messages)
    ratio = float(np.median(np.array(served) / np.array(plain)))
    name = "Foxglove, 1 client on every channel" + (", cameras" if cameras else "")
    return [
        FoxgloveCostRow("plain" + (", cameras" if cameras else ""), float(np.median(plain)), 1.0, 0.0),
        FoxgloveCostRow(name, float(np.median(served)), ratio, float(np.median(got))),
    ]
