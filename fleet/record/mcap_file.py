"""The recording file: MCAP with the `ros2` profile (rosbag2's layout), written and read through the `mcap` library.

Three kinds of channel live side by side:
- ROS 2 topics (`/tf`, `/<arm>/joint_states`, ...): schema encoding `ros2msg`, messages `cdr`, with rosbag2's
  `offered_qos_profiles` metadata (latched topics say transient_local, so players re-send them to late joiners);
- the raw bus: one channel per Zenoh key, exactly the bytes that crossed the bus (`msgpack`, no schema; the
  channel's metadata names the message type), which `fleet replay` plays back;
- one metadata record `clawfleet` with the scene (JSON), the run id and the protocol version.
Log and publish times are sim time in nanoseconds.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from fleet.bus.messages import PROTOCOL_VERSION
from fleet.record.ros_types import msgdef, serialize

MAGIC = b"\x89MCAP0\r\n"
RAW_ENCODING = "msgpack"
METADATA = "clawfleet"
LIBRARY = "clawfleet"
_QOS = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: {durability}\n  deadline: {{sec: 0, nsec: 0}}\n"
    "  lifespan: {{sec: 0, nsec: 0}}\n  liveliness: 1\n  liveliness_lease_duration: {{sec: 0, nsec: 0}}\n"
    "  avoid_ros_namespace_conventions: false\n"
)


def qos_profile(latched: bool) -> str:
    """rosbag2's `offered_qos_profiles` YAML: reliable, keep all; transient_local (1) for latched topics, else volatile
    (2)."""
    return _QOS.format(durability=1 if latched else 2)


SNAPSHOT_MEDIA_TYPE = "application/x-clawfleet-snapshot"


class RecordingWriter:
    """Writes one recording; use in a `with` block (the file is finished, with its index, on leaving)."""

    def __init__(self, path: str | Path, scene_json: str, run_id: str) -> None:
        self.path = Path(path)
        self._stream: IO[bytes] = open(self.path, "wb")
        self._writer = Writer(self._stream, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library=LIBRARY)
        self._writer.add_metadata(
            METADATA, {"scene": scene_json, "run_id": run_id, "protocol_version": str(PROTOCOL_VERSION)}
        )
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self.messages = 0
        self.closed = False

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._writer.finish()
            self._stream.close()

    def attach(self, name: str, data: bytes, log_time_ns: int, media_type: str) -> None:
        """A file carried in the recording (a snapshot of the run), at the sim time it belongs to."""
        self._writer.add_attachment(
            create_time=log_time_ns, log_time=log_time_ns, name=name, media_type=media_type, data=data
        )

    def _schema(self, typename: str) -> int:
        if typename not in self._schemas:
            self._schemas[typename] = self._writer.register_schema(typename, "ros2msg", msgdef(typename).encode())
        return self._schemas[typename]

    def _channel(self, topic: str, encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        if topic not in self._channels:
            self._channels[topic] = self._writer.register_channel(topic, encoding, schema_id, metadata)
        return self._channels[topic]

    def _add(self, channel: int, stamp_ns: int, data: bytes) -> None:
        sequence = self._sequence.get(channel, 0)
        self._sequence[channel] = sequence + 1
        self._writer.add_message(channel, stamp_ns, data, stamp_ns, sequence)
        self.messages += 1

    def ros(self, topic: str, message: object, stamp_ns: int, latched: bool = False) -> None:
        """A ROS 2 message (a typestore object) on `topic`."""
        self.ros_bytes(topic, message.__msgtype__, serialize(message), stamp_ns, latched)

    def ros_bytes(self, topic: str, typename: str, cdr: bytes, stamp_ns: int, latched: bool = False) -> None:
        """A ROS 2 message already serialised (CDR) on `topic`."""
        channel = self._channel(topic, "cdr", self._schema(typename), {"offered_qos_profiles": qos_profile(latched)})
        self._add(channel, stamp_ns, cdr)

    def raw(self, key: str, message_type: str, payload: bytes, stamp_ns: int) -> None:
        """The bytes of one bus message as they crossed the bus, on the channel named by its key."""
        self._add(self._channel(key, RAW_ENCODING, 0, {"clawfleet_type": message_type}), stamp_ns, payload)


class RecordingError(ValueError):
    """The file is not a clawfleet recording, or is cut short; the message is one line for the user."""


@dataclass(frozen=True)
class RawMessage:
    """One bus message as recorded: its key, the bytes, the sim time it was stamped with (ns)."""

    key: str
    payload: bytes
    stamp_ns: int


class Recording:
    """A recording opened for reading: its scene, its channels, its raw bus messages in time order."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise RecordingError(f"{self.path}: no such recording")
        with open(self.path, "rb") as f:
            if f.read(len(MAGIC)) != MAGIC:
                raise RecordingError(f"{self.path}: not an MCAP file")
        try:
            with open(self.path, "rb") as f:
                reader = make_reader(f)
                summary = reader.get_summary()
                meta = {m.name: m.metadata for m in reader.iter_metadata()}
        except (McapError, ValueError, EOFError, OSError) as exc:
            raise RecordingError(f"{self.path}: an MCAP file cut short or damaged ({_first_line(exc)})") from None
        if summary is None:
            raise RecordingError(f"{self.path}: the MCAP file has no summary (cut short while being written?)")
        if METADATA not in meta:
            raise RecordingError(f"{self.path}: an MCAP file, but not a clawfleet recording (no '{METADATA}' metadata)")
        self.metadata = meta[METADATA]
        self.run_id = self.metadata["run_id"]
        self.scene_json = self.metadata["scene"]
        self.channels = {c.topic: c for c in summary.channels.values()}
        self.schemas = {s.id: s for s in summary.schemas.values()}
        stats = summary.statistics
        self.start_ns = stats.message_start_time if stats else 0
        self.end_ns = stats.message_end_time if stats else 0
        self.message_counts = {
            summary.channels[cid].topic: n for cid, n in (stats.channel_message_counts.items() if stats else ())
        }
        # the snapshots it carries (`fleet run --snapshot-* --out` records them), by sim time
        self.snapshot_times_ns = {
            a.name: a.log_time for a in summary.attachment_indexes if a.media_type == SNAPSHOT_MEDIA_TYPE
        }

    def snapshot_name_at(self, time_s: float | None) -> str | None:
        """The name of the newest snapshot it carries at or before `time_s` (None: the last); None if there is none."""
        chosen = [(t, n) for n, t in self.snapshot_times_ns.items() if time_s is None or t <= round(time_s * 1e9)]
        return max(chosen)[1] if chosen else None

    def snapshot_at(self, time_s: float | None) -> tuple[str, bytes]:
        """The newest snapshot it carries at or before `time_s` (None: the last): its name and bytes; a
        `RecordingError` (one line) when there is none."""
        name = self.snapshot_name_at(time_s)
        if name is None:
            have = ", ".join(f"{t / 1e9:g} s" for t in sorted(self.snapshot_times_ns.values())) or "none"
            where = "" if time_s is None else f" at or before {time_s:g} s"
            raise RecordingError(f"{self.path}: no snapshot{where} (it carries: {have})")
        with open(self.path, "rb") as f:
            for attachment in make_reader(f).iter_attachments():
                if attachment.name == name:
                    return name, attachment.data
        raise RecordingError(f"{self.path}: snapshot {name} is listed but not in the file")

    @property
    def scene(self):
        from fleet.common.scene_loading import use_scene_robots
        from scenes.schema import Scene

        return use_scene_robots(Scene.model_validate_json(self.scene_json))

    @property
    def raw_keys(self) -> list[str]:
        return sorted(t for t, c in self.channels.items() if c.message_encoding == RAW_ENCODING)

    def raw_messages(self, keys: list[str] | None = None, start_ns: int | None = None) -> Iterator[RawMessage]:
        """Raw bus messages in time order (of one channel: in the order they were heard)."""
        topics = keys if keys is not None else self.raw_keys
        yield from (
            RawMessage(channel.topic, message.data, message.log_time)
            for _, channel, message in self._iter(topics, start_ns)
        )

    def messages(self, topics: list[str]) -> Iterator[tuple[str, object, str]]:
        """(topic, mcap message, schema name) for the given topics, in time order."""
        for schema, channel, message in self._iter(topics, None):
            yield channel.topic, message, schema.name if schema else ""

    def _iter(self, topics: list[str], start_ns: int | None):
        try:
            with open(self.path, "rb") as f:
                yield from make_reader(f).iter_messages(topics=topics, start_time=start_ns, log_time_order=True)
        except (McapError, ValueError, EOFError) as exc:
            raise RecordingError(f"{self.path}: cannot be read to the end ({_first_line(exc)})") from None


def _first_line(exc: BaseException) -> str:
    return (str(exc).splitlines() or [type(exc).__name__])[0][:160]
