"""The run log: every record as one JSON message of an MCAP file, readable after a kill.

:class:`McapRecorder` writes records as they come (no chunks, no compression) and hands
the bytes to the operating system every ``flush_every`` messages, so a process killed with
SIGKILL leaves a file whose flushed messages all read back; :meth:`McapRecorder.close`
writes the summary and the footer. :func:`read_log` reads such a file, whole or cut short.

Layout: one channel per (topic, record type), message encoding ``"json"``; each dataclass
type has a ``"jsonschema"`` schema that names its fields, plain mappings have none.
Message log and publish times are the record timestamps in ns (``round(t * 1e9)``, at
least 0); the exact timestamp stays in the record itself.

With a :class:`~twin.record.foxglove.FoxgloveStream`, the recorder also writes, after each
record, the Foxglove messages it gives (message encoding ``"protobuf"``, Foxglove's own
schemas): :func:`read_log` leaves them out.
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mcap.exceptions import EndOfFile, McapError
from mcap.opcode import Opcode
from mcap.records import Channel, McapRecord, Message
from mcap.stream_reader import StreamReader
from mcap.writer import MCAP0_MAGIC, CompressionType, Writer

from twin.closing import Closing
from twin.interruption import deferred_interrupts
from twin.record.codec import TYPE_KEY, decode, encode

if TYPE_CHECKING:
    from twin.record.foxglove import FoxgloveStream

__all__ = ["LogContents", "LogMessage", "McapRecorder", "read_log"]

MESSAGE_ENCODING = "json"
SCHEMA_ENCODING = "jsonschema"
FOXGLOVE_ENCODING = "protobuf"
"""The message encoding of the Foxglove channels (:mod:`twin.record.foxglove`), which
:func:`read_log` leaves out."""
LIBRARY = "camnet-twin twin.record"

_MAX_TIME_NS = 2**64 - 1
_RECORD_HEADER = struct.Struct("<BQ")
"""Every MCAP record starts with its opcode (1 byte) and its length (8 bytes, LE)."""


# --- writing -------------------------------------------------------------------------------


class McapRecorder(Closing):
    """A :class:`~twin.hal.recording.Recorder` that writes an MCAP file as it goes.

    Args:
        path: the file to write (replaced if it exists).
        flush_every: hand the written bytes to the operating system after this many
            messages (>= 1). What was handed over survives a kill of this process.
        foxglove: derives Foxglove's messages from the records, written after each record
            (None: none).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        flush_every: int = 8,
        foxglove: FoxgloveStream | None = None,
    ) -> None:
        if isinstance(flush_every, bool) or not isinstance(flush_every, int) or flush_every < 1:
            raise ValueError(f"flush_every must be an int >= 1, got {flush_every!r}")
        self.path = Path(path)
        self.flush_every = flush_every
        self._file = open(self.path, "wb")  # noqa: SIM115 (closed by close())
        self._writer = Writer(self._file, use_chunking=False, compression=CompressionType.NONE)
        self._writer.start(profile="", library=LIBRARY)
        self._file.flush()
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str | None], int] = {}
        self._sequence: dict[int, int] = {}
        self._count = 0
        self._closed = False
        self._foxglove = foxglove
        self._foxglove_channels = FoxgloveChannels(self._writer) if foxglove is not None else None

    @property
    def foxglove_counts(self) -> dict[str, int]:
        """Foxglove messages written so far, by topic."""
        return dict(self._foxglove_channels.counts) if self._foxglove_channels else {}

    @property
    def count(self) -> int:
        """Messages written so far."""
        return self._count

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    def record(self, topic: str, record: object, timestamp: float) -> None:
        """Write ``record`` (a dataclass record or a mapping) on ``topic`` at ``timestamp``, s."""
        if self._closed:
            raise ValueError(f"{self.path}: the log is closed; cannot record on {topic!r}")
        if not isinstance(topic, str) or not topic:
            raise ValueError(f"topic must be a non-empty str, got {topic!r}")
        time_ns = _time_ns(timestamp, topic)
        data = encode(record)
        payload = json.dumps(data, allow_nan=False, separators=(",", ":"))
        # An interruption waits until the record is written whole.
        with deferred_interrupts():
            add_message(
                self._writer,
                self._sequence,
                self._channel(topic, record),
                payload.encode("utf-8"),
                time_ns,
            )
            if self._foxglove is not None:
                self._write_foxglove(topic, data, float(timestamp), time_ns)
            self._count += 1
            if self._count % self.flush_every == 0:
                self.flush()

    def image(self, camera: str, image: Any, timestamp: float) -> None:
        """With a Foxglove stream, write the Foxglove messages of ``camera``'s image (a
        :class:`~twin.hal.readings.CameraImage`, the one its last LED observation was found
        in) at ``timestamp``, s; without one, nothing (images are not records)."""
        if self._foxglove is None or self._closed:
            return
        assert self._foxglove_channels is not None
        t = float(timestamp)
        time_ns = _time_ns(t, f"/camera/{camera}")
        topic = f"/camera/{camera}/image"
        with deferred_interrupts():
            try:
                messages = self._foxglove.image(camera, image.image, t)
            except (ValueError, KeyError, TypeError, IndexError) as exc:
                messages = self._foxglove.unreadable(topic, t, exc)
            for fox_topic, message in messages:
                self._foxglove_channels.write(fox_topic, message, time_ns)

    def _write_foxglove(self, topic: str, data: dict[str, Any], t: float, time_ns: int) -> None:
        """The Foxglove messages of one record, at its time. A record they cannot be drawn
        from (a field missing or of another type) is said so on Foxglove's log; the record
        itself is written all the same, and the run goes on."""
        assert self._foxglove is not None
        assert self._foxglove_channels is not None
        try:
            messages = self._foxglove.feed(topic, data, t)
        except (ValueError, KeyError, TypeError, IndexError) as exc:
            messages = self._foxglove.unreadable(topic, t, exc)
        for fox_topic, message in messages:
            self._foxglove_channels.write(fox_topic, message, time_ns)

    def flush(self) -> None:
        """Hand what was written to the operating system (no fsync)."""
        if not self._closed:
            self._file.flush()

    def close(self) -> None:
        """Write the summary and the footer and close the file. Calling it twice is harmless."""
        if self._closed:
            return
        self._closed = True
        with deferred_interrupts():  # the summary and footer, whole
            try:
                self._writer.finish()
            finally:
                self._file.close()

    def _channel(self, topic: str, record: object) -> int:
        type_name = type(record).__name__ if _is_record(record) else None
        key = (topic, type_name)
        if key not in self._channels:
            schema_id = self._schema(record) if type_name is not None else 0
            self._channels[key] = self._writer.register_channel(
                topic=topic, message_encoding=MESSAGE_ENCODING, schema_id=schema_id
            )
        return self._channels[key]

    def _schema(self, record: object) -> int:
        name = type(record).__name__
        if name not in self._schemas:
            data = json.dumps(_json_schema(record)).encode("utf-8")
            self._schemas[name] = self._writer.register_schema(name, SCHEMA_ENCODING, data)
        return self._schemas[name]


class FoxgloveChannels:
    """Writes Foxglove messages (:mod:`foxglove.messages`, each encoded by the SDK with its
    own schema: ``foxglove.FrameTransforms``...) with ``writer``, one channel per topic,
    registering each schema and channel the first time it is used.

    Attributes:
        counts: messages written, by topic.
    """

    def __init__(self, writer: Writer) -> None:
        self._writer = writer
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self.counts: dict[str, int] = {}

    def write(self, topic: str, message: Any, timestamp_ns: int) -> None:
        """Write ``message`` on ``topic`` at ``timestamp_ns`` (log and publish time)."""
        channel = self._channel(topic, message)
        add_message(self._writer, self._sequence, channel, message.encode(), timestamp_ns)
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _channel(self, topic: str, message: Any) -> int:
        if topic not in self._channels:
            schema = type(message).get_schema()
            if schema.name not in self._schemas:
                self._schemas[schema.name] = self._writer.register_schema(
                    schema.name, schema.encoding, schema.data
                )
            self._channels[topic] = self._writer.register_channel(
                topic=topic,
                message_encoding=FOXGLOVE_ENCODING,
                schema_id=self._schemas[schema.name],
            )
        return self._channels[topic]


def add_message(
    writer: Writer, sequences: dict[int, int], channel_id: int, data: bytes, time_ns: int
) -> None:
    """Write ``data`` on the channel ``channel_id`` at ``time_ns`` (its log and publish
    time, ns), numbered in its channel's sequence (``sequences``, by channel, counted up)."""
    sequence = sequences.get(channel_id, 0)
    sequences[channel_id] = sequence + 1
    writer.add_message(
        channel_id=channel_id,
        log_time=time_ns,
        data=data,
        publish_time=time_ns,
        sequence=sequence,
    )


def _is_record(record: object) -> bool:
    return is_dataclass(record) and not isinstance(record, type)


def _time_ns(timestamp: float, topic: str) -> int:
    """A timestamp in s as MCAP time in ns, at least 0."""
    t = float(timestamp)
    if not math.isfinite(t):
        raise ValueError(f"timestamp on {topic!r} must be finite, got {timestamp} s")
    ns = max(0, round(t * 1e9))
    if ns > _MAX_TIME_NS:
        raise ValueError(f"timestamp on {topic!r} is beyond the MCAP time range: {timestamp} s")
    return ns


def _json_schema(record: Any) -> dict[str, Any]:
    """A JSON schema naming the fields of a dataclass record (their values are not typed)."""
    cls = type(record)
    summary = " ".join((cls.__doc__ or cls.__name__).strip().split("\n\n")[0].split())
    names = [f.name for f in fields(record)]
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": cls.__name__,
        "description": summary,
        "type": "object",
        "properties": {TYPE_KEY: {"const": cls.__name__}, **{n: {} for n in names}},
        "required": [TYPE_KEY, *names],
    }


# --- reading -------------------------------------------------------------------------------


@dataclass(frozen=True)
class LogMessage:
    """One message of a log.

    Attributes:
        topic: the channel's topic.
        timestamp: the message's log time, s (ns resolution).
        data: the message's JSON, with ``"_type"`` for records.
    """

    topic: str
    timestamp: float
    data: dict[str, Any]

    def decode(self) -> object:
        """The record the message holds (the dict itself for unknown types)."""
        return decode(self.data)


@dataclass(frozen=True)
class LogContents:
    """What a log holds.

    Attributes:
        path: the file read.
        messages: every whole message, in file order.
        complete: whether the file ends with its footer (False: the writer did not close it,
            e.g. it was killed, and what followed the last whole record is lost).
        unread_bytes: bytes after the last whole record that could not be read (a record cut
            short); 0 for a complete file.
    """

    path: Path
    messages: list[LogMessage]
    complete: bool
    unread_bytes: int = 0

    @property
    def topics(self) -> tuple[str, ...]:
        """The topics that carry messages, in the order of their first message."""
        return tuple(dict.fromkeys(m.topic for m in self.messages))

    def records(self, topic_prefix: str | None = None) -> list[object]:
        """The decoded records (see :func:`~twin.record.codec.decode`), in file order, of the
        messages whose topic starts with ``topic_prefix`` (all when None)."""
        return [
            m.decode()
            for m in self.messages
            if topic_prefix is None or m.topic.startswith(topic_prefix)
        ]


def read_log(path: str | os.PathLike[str]) -> LogContents:
    """Read an MCAP log of JSON messages, whole or cut short (its Foxglove channels, if
    any, left out).

    A file cut anywhere (a killed writer) gives every whole message before the cut and
    ``complete=False``. Raises FileNotFoundError for a missing file and ValueError, naming
    the file, for an empty one, one that is not MCAP, or a record that does not parse.
    """
    path = Path(path)
    data = path.read_bytes()
    if not data:
        raise ValueError(f"{path}: the file is empty; expected an MCAP log")
    if not (data.startswith(MCAP0_MAGIC) or MCAP0_MAGIC.startswith(data)):
        raise ValueError(f"{path}: not an MCAP file (it does not start with the MCAP magic)")
    end, complete = _whole_records_end(data)
    records = _stream_records(data[: end + (len(MCAP0_MAGIC) if complete else 0)], path)
    messages = _messages(records, path)
    return LogContents(path, messages, complete, unread_bytes=0 if complete else len(data) - end)


def _whole_records_end(data: bytes) -> tuple[int, bool]:
    """Where the last whole record of an MCAP file ends, bytes, and whether the footer and
    the closing magic follow. Only the record framing is read here."""
    pos = len(MCAP0_MAGIC)
    if len(data) < pos:
        return len(data), False
    while pos + _RECORD_HEADER.size <= len(data):
        opcode, length = _RECORD_HEADER.unpack_from(data, pos)
        end = pos + _RECORD_HEADER.size + length
        if end > len(data):
            break
        pos = end
        if opcode == Opcode.FOOTER:
            return pos, data[pos : pos + len(MCAP0_MAGIC)] == MCAP0_MAGIC
    return pos, False


def _stream_records(data: bytes, path: Path) -> list[McapRecord]:
    """The records of whole MCAP records (with the magic) read by mcap's stream reader."""
    if len(data) < len(MCAP0_MAGIC):
        return []
    out: list[McapRecord] = []
    reader = StreamReader(io.BytesIO(data), record_size_limit=None)
    try:
        for rec in reader.records:
            out.append(rec)
    except EndOfFile:
        pass  # the data stops after its last whole record: no footer (a killed writer)
    except (McapError, struct.error, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: corrupt MCAP record after {len(out)} records: {exc}") from exc
    return out


def _messages(records: list[McapRecord], path: Path) -> list[LogMessage]:
    channels: dict[int, Channel] = {}
    out: list[LogMessage] = []
    foxglove: set[int] = set()
    for rec in records:
        if isinstance(rec, Channel):
            channels[rec.id] = rec
            if rec.message_encoding == FOXGLOVE_ENCODING:
                foxglove.add(rec.id)
        elif isinstance(rec, Message) and rec.channel_id not in foxglove:
            out.append(_log_message(rec, channels, path))
    return out


def _log_message(msg: Message, channels: dict[int, Channel], path: Path) -> LogMessage:
    channel = channels.get(msg.channel_id)
    if channel is None:
        raise ValueError(f"{path}: a message on channel {msg.channel_id}, which was not declared")
    if channel.message_encoding != MESSAGE_ENCODING:
        raise ValueError(
            f"{path}: topic {channel.topic!r} is encoded as {channel.message_encoding!r}; "
            f"this log reader reads {MESSAGE_ENCODING!r} only"
        )
    try:
        data = json.loads(msg.data)
    except ValueError as exc:
        raise ValueError(f"{path}: a message on {channel.topic!r} is not JSON: {exc}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a message on {channel.topic!r} is not a JSON object")
    return LogMessage(channel.topic, msg.log_time / 1e9, data)
