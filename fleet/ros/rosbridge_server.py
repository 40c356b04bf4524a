"""A rosbridge v2 server for one running line (the protocol of rosbridge_suite 2.x for ROS 2, JSON): clients
subscribe to the line's topics, call its services and rosapi, send `FollowJointTrajectory` goals and cancel them,
and publish `trajectory_msgs/JointTrajectory` to `/<arm>/joint_trajectory` (fire and forget). Anything it cannot
do is answered with a `status` error to that client; the line is never touched by a bad request.

The line side is `LineBus`: the node gives it the bus (goals, e-stop, pause) and feeds `on_bus` with what the bus
carries, on this server's event loop.
"""

from __future__ import annotations

import asyncio
import json
import math
import sys
from collections.abc import Callable

import cbor2
import websockets

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, CameraImage, GoalResultMsg, LineView
from fleet.record.ros_types import TYPESTORE, sim_ns
from fleet.ros import names
from fleet.ros.line_actions import GoalReplies, LineActions
from fleet.ros.line_services import LineBus, ServiceError, answer_line_service
from fleet.ros.line_topics import LineTopics
from fleet.ros.ros_json import to_json
from fleet.ros.rosapi import Rosapi
from fleet.ros.rosauth import auth_problem, auth_request
from fleet.ros.rosbridge_client import COMPRESSIONS, Client, Subscription
from robots.registry import get_robot
from scenes.schema import IMAGE_KINDS, Scene

MAX_MESSAGE_BYTES = 1 << 20


class RequestError(ValueError):
    """A request this server refuses; the message is the `status` text the client gets."""


def _field(message: dict, name: str, kind: type | tuple[type, ...], default: object = ...) -> object:
    value = message.get(name, default)
    if value is ... or not isinstance(value, kind) or isinstance(value, bool) and kind in (int, float):
        raise RequestError(f"'{message.get('op')}' needs {name!r} as {getattr(kind, '__name__', kind)}")
    return value


MAX_DEPTH = 64  # JSON levels a request may nest (ROS messages nest a few; Python's recursion ends near 1000)
TOO_DEEP = f"JSON nested too deeply (this server reads {MAX_DEPTH} levels)"


def nested_deeper(value: object, depth: int) -> bool:
    """Whether a decoded JSON value nests lists or objects deeper than `depth` (walked without recursion)."""
    stack = [(value, 1)]
    while stack:
        v, level = stack.pop()
        if isinstance(v, dict | list):
            if level > depth:
                return True
            stack.extend((x, level + 1) for x in (v.values() if isinstance(v, dict) else v))
    return False


def echoable_id(value: object) -> object:
    """A request's `id` as its answers echo it: a string, whole number, bool or finite number as sent, anything else
    (an infinity, a list, an object) as its text (answers are strict JSON)."""
    if value is None or isinstance(value, str | bool | int) or (isinstance(value, float) and math.isfinite(value)):
        return value
    return str(value)


class PublishEncodings:
    """One published message of `topic` (a typestore message of `typename`) as rosbridge sends it, in each
    compression a subscriber asked for, each made once: JSON text (none), CBOR of the same `publish` (byte sequences
    as bytes), or CBOR around the message's CDR bytes and the time it was heard (cbor-raw: `msg` is
    `{secs, nsecs, bytes}`, the line's sim time)."""

    def __init__(self, topic: str, msg: object, typename: str, clock_s: float) -> None:
        self.topic, self.msg, self.typename, self.clock_s = topic, msg, typename, clock_s
        self._made: dict[str, str | bytes] = {}

    def __call__(self, compression: str) -> str | bytes:
        if compression not in self._made:
            self._made[compression] = self._encode(compression)
        return self._made[compression]

    def _encode(self, compression: str) -> str | bytes:
        if compression == "cbor":
            return cbor2.dumps({"op": "publish", "topic": self.topic, "msg": to_json(self.msg, raw_bytes=True)})
        if compression == "cbor-raw":
            ns = sim_ns(self.clock_s)
            cdr = bytes(TYPESTORE.serialize_cdr(self.msg, self.typename))
            raw = {"secs": ns // 1_000_000_000, "nsecs": ns % 1_000_000_000, "bytes": cdr}
            return cbor2.dumps({"op": "publish", "topic": self.topic, "msg": raw})
        return json.dumps({"op": "publish", "topic": self.topic, "msg": to_json(self.msg)}, allow_nan=False)


class RosbridgeServer:
    """The line's rosbridge: `serve(host, port, stop)` until `stop()` says so."""

    def __init__(
        self, scene: Scene, bus: LineBus, secret: str | None = None, max_rate_hz: float = names.DEFAULT_MAX_RATE_HZ
    ) -> None:
        self.bus = bus
        self.secret = secret  # with one, a client's first request must be `auth` with a valid MAC (`rosauth`)
        self.topics = LineTopics(scene, max_rate_hz)
        arms = self.topics.arms
        self.actions = LineActions({a.name: get_robot(a.model) for a in scene.arms}, bus.send_goal)
        self.rosapi = Rosapi(arms, lambda: max(self.topics.clock_s, 0.0), self.topics.types)
        self.clients: list[Client] = []
        self.drops = DropCounter()
        self._decoders = {
            "state": Decoder(ArmState, self.drops),
            "result": Decoder(GoalResultMsg, self.drops),
            "view": Decoder(LineView, self.drops),
        } | {kind: Decoder(CameraImage, self.drops) for kind in IMAGE_KINDS}
        self._numbers = 0
        self.requests_refused = 0
        self.requests_failed = 0  # requests that raised where no check refused them: each a bug to report

    # --- the line -----------------------------------------------------------------
    def on_bus(self, key: str, payload: bytes) -> None:
        """One message the bus carried: to the topics someone listens to, the actions' feedback and results."""
        leaf = key.rsplit("/", 1)[-1]
        decoder = self._decoders.get(leaf)
        msg = decoder.decode(key, payload) if decoder else None
        if msg is None:
            return
        wanted = {t for c in self.clients for t in c.subscriptions}
        if isinstance(msg, ArmState):
            self.actions.on_state(msg)
        elif isinstance(msg, GoalResultMsg):
            self.actions.on_result(msg)
            self._publish(self.topics.from_result(msg, wanted))
        elif isinstance(msg, CameraImage):
            self._publish(self.topics.from_camera(msg, wanted))
        else:
            self._publish(self.topics.from_view(msg, wanted))

    def flush_held(self) -> None:
        """The newest view the rate cap held back, once it may go (`LineTopics.held_back`)."""
        self._publish(self.topics.held_back({t for c in self.clients for t in c.subscriptions}))

    def needed(self, keys: Keys) -> set[str]:
        """The bus keys this server needs now: the states of arms its clients' goals drive or whose own joint states
        they watch, the line's view while they watch a topic it feeds (`OnDemandSubscriptions`)."""
        wanted = {t for c in self.clients for t in c.subscriptions}
        return self.topics.keys_needed(keys, wanted, self.actions.arms_in_flight())

    def _publish(self, messages: list[tuple[str, object]]) -> None:
        for topic, msg in messages:
            encoded = PublishEncodings(topic, msg, self.topics.types[topic], self.topics.clock_s)
            for client in self.clients:
                client.offer(topic, encoded)

    # --- clients ------------------------------------------------------------------
    async def serve(self, host: str, port: int, stop: Callable[[], bool], on_listening: Callable[[int], None]) -> None:
        async with websockets.serve(self._connection, host, port, max_size=MAX_MESSAGE_BYTES) as server:
            on_listening(server.sockets[0].getsockname()[1])
            while not stop():
                await asyncio.sleep(0.05)

    async def _connection(self, websocket) -> None:
        self._numbers += 1
        client = Client(websocket, self._numbers)
        self.clients.append(client)
        pump = asyncio.create_task(client.pump())
        try:
            async for raw in websocket:
                if not self.on_request(client, raw):
                    await asyncio.sleep(0.05)  # the status goes out first
                    await websocket.close(1008, "authentication failed")
                    break
        except websockets.ConnectionClosed:
            pass
        finally:
            pump.cancel()
            self.clients.remove(client)
            self.actions.forget(client)

    def on_request(self, client: Client, raw: str | bytes) -> bool:
        """One request from a client; a bad one gets a `status` error naming what is wrong. False: the connection
        is to be closed (it did not authenticate where the server needs it)."""
        op_id = None
        try:
            try:
                message = json.loads(raw)
            except (ValueError, UnicodeDecodeError) as exc:
                raise RequestError(f"not JSON: {str(exc)[:80]}") from None
            except RecursionError:
                raise RequestError(TOO_DEEP) from None
            if nested_deeper(message, MAX_DEPTH):
                raise RequestError(TOO_DEEP)
            if not isinstance(message, dict):
                raise RequestError("a request is a JSON object with an 'op'")
            if "id" in message:  # echoed in every answer: kept to what JSON can carry back
                message["id"] = echoable_id(message["id"])
            op_id = message.get("id")
            if self.secret is not None and not client.authenticated:
                return self._authenticate(client, message)
            handler = self._ops.get(str(message.get("op")))
            if handler is None:
                raise RequestError(f"unknown op {message.get('op')!r} (known: {', '.join(self._ops)})")
            handler(self, client, message)
        except RequestError as exc:
            self.requests_refused += 1
            client.status("error", str(exc), op_id)
        except Exception as exc:  # noqa: BLE001 - a request no check foresaw: its client is told, the server goes on
            self.requests_failed += 1
            print(f"fleet rosbridge: a request failed: {type(exc).__name__}: {str(exc)[:200]}", file=sys.stderr)
            client.status("error", f"the server could not handle this request ({type(exc).__name__})", op_id)
        return True

    def _authenticate(self, client: Client, message: dict) -> bool:
        """The first request where the server has a secret: `auth`, with a MAC for this connection."""
        if message.get("op") != "auth":
            problem = "authenticate first: this server takes an 'auth' request before any other"
        else:
            try:
                problem = auth_problem(auth_request(message), self.secret, client.peer_ip, client.local_ip)
            except ValueError as exc:
                problem = str(exc)
        if problem:
            self.requests_refused += 1
            client.status("error", f"authentication failed: {problem}")
            return False
        client.authenticated = True
        return True

    def _subscribe(self, client: Client, m: dict) -> None:
        topic = _field(m, "topic", str)
        known = self.topics.types.get(topic)
        if known is None:
            raise RequestError(f"no topic {topic!r} on this line (topics: {', '.join(self.topics.types)})")
        if m.get("type") not in (None, "", known) and m.get("type") != known.replace("/msg/", "/"):
            raise RequestError(f"{topic} is {known}, not {m['type']}")
        sub = client.subscriptions.setdefault(topic, Subscription())
        sub.ids.add(str(m.get("id")))
        sub.throttle_s = float(_field(m, "throttle_rate", int, 0)) / 1000.0
        sub.queue_length = int(_field(m, "queue_length", int, 0))
        compression = _field(m, "compression", str, "none") or "none"
        if compression not in COMPRESSIONS:
            raise RequestError(
                f"compression {compression!r} is not served (this server sends {', '.join(COMPRESSIONS)})"
            )
        sub.compression = compression
        if topic in self.topics.latched:
            latched = PublishEncodings(topic, self.topics.latched[topic], known, self.topics.clock_s)
            client.send_text(latched(compression))

    def _unsubscribe(self, client: Client, m: dict) -> None:
        topic = _field(m, "topic", str)
        sub = client.subscriptions.get(topic)
        if sub is not None:
            sub.ids.discard(str(m.get("id")))
            if not sub.ids or m.get("id") is None:
                del client.subscriptions[topic]

    def _advertise(self, client: Client, m: dict) -> None:
        """Checked only: a publication needs no advertisement first (rosbridge advertises on the first one)."""
        topic, kind = _field(m, "topic", str), _field(m, "type", str)
        self._commanded_arm(topic)
        if kind.replace("/msg/", "/") != "trajectory_msgs/JointTrajectory":
            raise RequestError(f"{topic} takes trajectory_msgs/msg/JointTrajectory, not {kind}")

    def _unadvertise(self, client: Client, m: dict) -> None:
        _field(m, "topic", str)

    def _publish_op(self, client: Client, m: dict) -> None:
        topic = _field(m, "topic", str)
        arm = self._commanded_arm(topic)
        msg = _field(m, "msg", dict)
        try:
            self.actions.send_trajectory(arm, msg)
        except ValueError as exc:
            raise RequestError(f"{topic}: {exc}") from None

    def _commanded_arm(self, topic: str) -> str:
        arm = topic.strip("/").split("/")[0]
        if topic != f"/{arm}/joint_trajectory" or arm not in self.topics.arms:
            commanded = ", ".join(f"/{a}/joint_trajectory" for a in self.topics.arms)
            raise RequestError(f"{topic} is not a topic this line takes (it takes {commanded})")
        return arm

    def _call_service(self, client: Client, m: dict) -> None:
        service, args = _field(m, "service", str), m.get("args") or {}
        if not isinstance(args, dict):
            raise RequestError("call_service needs 'args' as an object")
        try:
            if service in names.SERVICE_TYPES:
                values = answer_line_service(service, args, self.bus)
            else:
                values = self.rosapi.answer(service, args)
        except ServiceError as exc:
            raise RequestError(str(exc)) from None
        except KeyError:
            raise RequestError(f"no service {service!r} (services: {', '.join(self.rosapi.services)})") from None
        out = {"op": "service_response", "service": service, "values": values, "result": True}
        if m.get("id") is not None:
            out["id"] = m["id"]
        client.send(out)

    def _send_action_goal(self, client: Client, m: dict) -> None:
        action, kind = _field(m, "action", str), _field(m, "action_type", str)
        known = self.rosapi.actions.get(action)
        if known is None:
            raise RequestError(f"no action {action!r} (actions: {', '.join(self.rosapi.actions)})")
        if kind != known:
            raise RequestError(f"{action} is {known}, not {kind}")
        op_id = m.get("id")

        def result(r) -> None:
            out = {
                "op": "action_result",
                "action": action,
                "values": r.values,
                "status": r.status,
                "result": r.accepted,
            }
            client.send(to_json(out if op_id is None else out | {"id": op_id}))

        def feedback(values: dict) -> None:
            client.send({"op": "action_feedback", "id": op_id, "action": action, "values": values})

        replies = GoalReplies(result, feedback if m.get("feedback") else None)
        self.actions.send(client, op_id, action, m.get("args"), replies)

    def _cancel_action_goal(self, client: Client, m: dict) -> None:
        if not self.actions.cancel(client, m.get("id")):
            raise RequestError(f"no goal {m.get('id')!r} of this client in flight to cancel")

    _ops = {
        "subscribe": _subscribe,
        "unsubscribe": _unsubscribe,
        "advertise": _advertise,
        "unadvertise": _unadvertise,
        "publish": _publish_op,
        "call_service": _call_service,
        "send_action_goal": _send_action_goal,
        "cancel_action_goal": _cancel_action_goal,
    }
