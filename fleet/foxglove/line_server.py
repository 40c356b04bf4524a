"""The line on a Foxglove WebSocket server: the same topics as every ROS front end (`LineTopics`: joint states,
`/tf` and `/tf_static`, the cell and the parts as markers, the cameras, `/rosout`, `/clock`), each a channel of
ROS 2 messages in CDR with their full definitions (`ros2msg`), which the Foxglove app decodes natively; the cell
and the parts as Foxglove scene entities too; the line's status as a JSON channel that plots; the server's time is
the line's sim time; `/estop`, `/pause` and `/resume` as services (JSON requests, as the ROS services take them)."""

from __future__ import annotations

import json
import threading

import foxglove
import msgspec
from foxglove.channels import SceneUpdateChannel
from foxglove.websocket import (
    Capability,
    ChannelView,
    Client,
    PlaybackControlRequest,
    PlaybackState,
    ServiceRequest,
)

from fleet.bus.messages import LineView, SimStatus
from fleet.foxglove.playback import RecordingPlayback
from fleet.foxglove.scene_entities import CELL, PARTS, scene_update
from fleet.record.ros_types import serialize, sim_ns
from fleet.ros import names
from fleet.ros.line_services import LineBus, ServiceError, answer_line_service
from fleet.ros.line_topics import LineTopics
from fleet.ros.rosapi_types import full_text
from scenes.schema import Scene

STATUS = "/line/status"  # the sim's status (`SimStatus`): sim time, pause, e-stop, utilisation per arm, contacts
SERVICE_SCHEMAS = {
    names.ESTOP: {"type": "object", "properties": {"data": {"type": "boolean"}}, "required": ["data"]},
    names.PAUSE: {"type": "object"},
    names.RESUME: {"type": "object"},
}
ANSWER_SCHEMA = {"type": "object", "properties": {"success": {"type": "boolean"}, "message": {"type": "string"}}}


class Subscribed:
    """The server's listener: the topics some Foxglove client subscribes to now, and those a client just subscribed
    to (a latched topic is logged again for it); a playback request goes to `playback`, if any. The server calls it
    on its own threads: it only counts, under a lock."""

    def __init__(self, playback: RecordingPlayback | None = None) -> None:
        self._lock = threading.Lock()
        self._clients: dict[str, set[int]] = {}
        self._new: set[str] = set()
        self.playback = playback

    def on_playback_control_request(self, request: PlaybackControlRequest) -> PlaybackState | None:
        return self.playback.on_request(request) if self.playback is not None else None

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            self._clients.setdefault(channel.topic, set()).add(client.id)
            self._new.add(channel.topic)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        with self._lock:
            self._clients.get(channel.topic, set()).discard(client.id)

    def topics(self) -> set[str]:
        with self._lock:
            return {t for t, clients in self._clients.items() if clients}

    def take_new(self) -> set[str]:
        with self._lock:
            new, self._new = self._new, set()
        return new


def _json_schema(schema: dict) -> foxglove.MessageSchema:
    return foxglove.MessageSchema(
        encoding="json", schema=foxglove.Schema(name="", encoding="jsonschema", data=json.dumps(schema).encode())
    )


class FoxgloveLine:
    """One scene's line on a Foxglove server of its own (`start` it on `host:port`; port 0: a free one)."""

    def __init__(
        self,
        scene: Scene,
        bus: LineBus,
        max_rate_hz: float = names.DEFAULT_MAX_RATE_HZ,
        playback: RecordingPlayback | None = None,
    ) -> None:
        self.topics = LineTopics(scene, max_rate_hz)
        self.playback = playback
        self.bus = bus
        self.context = foxglove.Context()
        self.channels = {topic: self._ros_channel(topic, typename) for topic, typename in self.topics.types.items()}
        self.status = foxglove.Channel(STATUS, schema=_status_schema(), context=self.context)
        self.scene = {topic: SceneUpdateChannel(topic, context=self.context) for topic in (CELL, PARTS)}
        self.subscribed = Subscribed(playback)
        self.server: foxglove.WebSocketServer | None = None
        self.sent = self.refused = 0

    def _ros_channel(self, topic: str, typename: str) -> foxglove.Channel:
        schema = foxglove.Schema(name=typename, encoding="ros2msg", data=full_text(typename).encode())
        return foxglove.Channel(topic, schema=schema, message_encoding="cdr", context=self.context)

    def start(self, host: str, port: int) -> int:
        """Serve on `host:port`; the port it serves on."""
        services = [
            foxglove.Service(
                name,
                schema=foxglove.ServiceSchema(
                    names.SERVICE_TYPES[name], request=_json_schema(schema), response=_json_schema(ANSWER_SCHEMA)
                ),
                handler=self._answer,
            )
            for name, schema in SERVICE_SCHEMAS.items()
        ]
        playback = self.playback
        self.server = foxglove.start_server(
            name="clawfleet",
            host=host,
            port=port,
            capabilities=[Capability.Time, Capability.Services, *([Capability.PlaybackControl] if playback else [])],
            playback_time_range=playback.time_range_ns if playback else None,
            supported_encodings=["json"],
            services=services,
            server_listener=self.subscribed,
            context=self.context,
        )
        return self.server.port

    def wanted(self) -> set[str]:
        """The line's ROS topics to build now: those some client subscribes to, and the parts' markers while the
        parts' scene entities are (only those are built)."""
        subscribed = self.subscribed.topics()
        return (subscribed & set(self.channels)) | ({names.PARTS} if PARTS in subscribed else set())

    def publish(self, out: list[tuple[str, object]]) -> None:
        """ROS messages of the line's topics (`LineTopics`), each logged at the line's sim time; the parts'
        markers as scene entities too."""
        subscribed = self.subscribed.topics()
        for topic, message in out:
            if topic == names.PARTS and PARTS in subscribed:
                self._log_scene(PARTS, message)
            if topic in subscribed:
                self.channels[topic].log(serialize(message), log_time=sim_ns(self.topics.clock_s))
                self.sent += 1

    def _log_scene(self, topic: str, markers: object) -> None:
        ros = self.topics.ros
        update = scene_update(markers, ros.DELETEALL, ros.CYLINDER)
        self.scene[topic].log(update, log_time=sim_ns(max(self.topics.clock_s, 0.0)))
        self.sent += 1

    def tick_clock(self) -> None:
        """The server's time: the line's sim time, as far as its views have said; in playback, the app is told
        once when the recording's end is reached."""
        if self.server is None:
            return
        if self.topics.clock_s >= 0:
            self.server.broadcast_time(sim_ns(self.topics.clock_s))
        if self.playback is not None and self.playback.ended_now():
            self.server.broadcast_playback_state(self.playback.state())

    def on_view(self, view: LineView) -> None:
        """A view of the line: its topics, and the server's time. In playback the clock follows the recording
        wherever the app seeks it (back, too)."""
        if self.playback is not None:
            self.topics.clock_s = -1.0
        self.publish(self.topics.from_view(view, self.wanted()))
        self.tick_clock()

    def publish_latched(self) -> None:
        """The static transforms and the cell's markers, again for the clients that just subscribed to them."""
        new = self.subscribed.take_new()
        for topic in new & set(self.topics.latched):
            self.publish([(topic, self.topics.latched[topic])])
        if CELL in new:
            self._log_scene(CELL, self.topics.latched[names.CELL])

    def on_status(self, status: SimStatus) -> None:
        fields = msgspec.structs.asdict(status)
        del fields["version"]
        self.status.log(fields, log_time=sim_ns(status.sim_time_s))

    def _answer(self, request: ServiceRequest) -> bytes:
        """A service call: JSON in (`{"data": true}` for `/estop`), JSON out (`success`, `message`)."""
        try:
            args = json.loads(request.payload or b"{}")
            if not isinstance(args, dict):
                raise ServiceError(f"{request.service_name} takes a JSON object")
            values = answer_line_service(request.service_name, args, self.bus)
        except (ServiceError, ValueError) as exc:
            self.refused += 1
            values = {"success": False, "message": str(exc)}
        return json.dumps(values).encode()

    def stop(self) -> None:
        if self.server is not None:
            self.server.stop()
            self.server = None


def _status_schema() -> dict:
    """The JSON schema of `/line/status`: the sim's status fields (Foxglove's plot panel lists them)."""
    numbers = {"type": "number"}
    props = {f: numbers for f in ("sim_time_s", "speed", "latency_p99_ms", "last_contact_s")}
    props |= {f: {"type": "integer"} for f in ("tick", "contact_ticks", "dropped_messages")}
    props |= {f: {"type": "boolean"} for f in ("paused", "estop")}
    props |= {"mode": {"type": "string"}, "utilisation": {"type": "array", "items": numbers}}
    props |= {f: {"type": "array", "items": {"type": "string"}} for f in ("contact_pairs", "arms_lost")}
    return {"type": "object", "properties": props}
