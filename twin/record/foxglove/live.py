"""The same Foxglove channels served live over Foxglove's WebSocket protocol while a run goes
on (``twin run --live``), with the SDK's server (``foxglove.start_server``).

The run's thread only puts each message in a bounded queue (never waiting: a message that
does not fit is dropped and counted); a thread of the server's own encodes them and hands
them to the SDK, whose server keeps a bounded backlog per client. A client that reads
slowly therefore never slows the campaign, and what the campaign records is the same with
the server on or off.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Mapping
from typing import Any

import foxglove
from foxglove import messages as fox_messages

from twin.closing import Closing
from twin.record.foxglove.stream import TOPICS, FoxgloveStream, Message

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "LiveServer", "LiveStream"]

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
QUEUE_SIZE = 8192
"""Messages waiting to be served at most; more are dropped (and counted)."""
_STOP = object()


class LiveServer(Closing):
    """Foxglove's WebSocket server (``foxglove.websocket.v1``), serving every topic of
    :data:`~twin.record.foxglove.stream.TOPICS` from the moment it starts, and each
    camera's topics (:func:`~twin.record.foxglove.images.camera_topics`) from their first
    message on.

    Args:
        host: the address to listen on (localhost by default).
        port: the TCP port; 0 picks a free one (see :attr:`port`).
        queue_size: messages waiting to be served at most (>= 1).

    Raises:
        OSError: the port cannot be listened on (in use, not allowed).

    Attributes:
        offered: messages the run handed over. sent: messages given to the SDK's server.
        dropped: messages dropped because the queue was full.
    """

    def __init__(
        self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, queue_size: int = QUEUE_SIZE
    ) -> None:
        if queue_size < 1:
            raise ValueError(f"queue_size must be >= 1, got {queue_size}")
        self._context = foxglove.Context()
        self._channels = {
            topic: _channel(topic, schema, self._context) for topic, schema in TOPICS.items()
        }
        try:
            self._server = foxglove.start_server(
                name="camnet twin", host=host, port=port, context=self._context
            )
        except RuntimeError as exc:  # the SDK says why the socket could not be bound
            raise OSError(f"cannot serve Foxglove on {host}:{port}: {exc}") from exc
        self.host = host
        self.port: int = self._server.port
        self.offered = 0
        self.sent = 0
        self.dropped = 0
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self._closed = False
        self._thread = threading.Thread(target=self._drain, name="foxglove-live", daemon=True)
        self._thread.start()

    @property
    def closed(self) -> bool:
        """Whether the server was stopped."""
        return self._closed

    def has_clients(self) -> bool:
        """Whether a client is subscribed to every topic."""
        return all(c.has_sinks() for c in self._channels.values())

    def offer(self, messages: list[Message], t: float) -> None:
        """Queue ``messages`` (topic, message) at the campaign's time ``t`` s, without waiting:
        what does not fit is dropped."""
        if self._closed:
            return
        time_ns = max(0, round(float(t) * 1e9))  # as the log's times
        for topic, message in messages:
            if topic not in self._channels:  # a camera's topics, from its first message on
                schema = type(message).get_schema().name
                self._channels[topic] = _channel(topic, schema, self._context)
            self.offered += 1
            try:
                self._queue.put_nowait((topic, message, time_ns))
            except queue.Full:
                self.dropped += 1

    def tee(self, stream: FoxgloveStream) -> LiveStream:
        """``stream`` whose messages are also served here."""
        return LiveStream(stream, self)

    def close(self) -> None:
        """Serve what is queued, then stop the server. Calling it twice is harmless."""
        if self._closed:
            return
        self._closed = True
        self._queue.put(_STOP)  # the drain always makes room
        self._thread.join(timeout=10.0)
        self._server.stop()

    def _drain(self) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            topic, message, time_ns = item
            channel = self._channels[topic]
            if channel.has_sinks():  # nobody listening: nothing to encode
                channel.log(message.encode(), log_time=time_ns)
            self.sent += 1


class LiveStream:
    """A :class:`FoxgloveStream` (for :class:`twin.record.McapRecorder`) whose messages are
    also offered to a :class:`LiveServer`; the messages returned are the stream's own."""

    def __init__(self, stream: FoxgloveStream, server: LiveServer) -> None:
        self.stream = stream
        self.server = server

    def feed(self, topic: str, data: Mapping[str, Any], t: float) -> list[Message]:
        out = self.stream.feed(topic, data, t)
        if out:
            self.server.offer(out, t)
        return out

    def image(self, camera: str, image: Any, t: float) -> list[Message]:
        out = self.stream.image(camera, image, t)
        self.server.offer(out, t)
        return out

    def unreadable(self, topic: str, t: float, exc: Exception) -> list[Message]:
        out = self.stream.unreadable(topic, t, exc)
        self.server.offer(out, t)
        return out


def _channel(topic: str, schema_name: str, context: foxglove.Context) -> foxglove.Channel:
    """A protobuf channel of ``topic`` with the SDK's schema ``schema_name``
    (``foxglove.FrameTransforms``...)."""
    message_type = getattr(fox_messages, schema_name.removeprefix("foxglove."))
    schema = message_type.get_schema()
    return foxglove.Channel(
        topic,
        schema=foxglove.Schema(name=schema.name, encoding=schema.encoding, data=schema.data),
        message_encoding="protobuf",
        context=context,
    )


class LiveRecorder:
    """A :class:`~twin.hal.recording.Recorder` whose records are drawn by a
    :class:`FoxgloveStream` and served by a :class:`LiveServer` (not logged): what
    ``twin emulate --live`` shows of the emulated world's truth."""

    def __init__(self, server: LiveServer, stream: FoxgloveStream) -> None:
        self.server = server
        self.stream = stream

    def record(self, topic: str, record: object, timestamp: float) -> None:
        from twin.record.codec import encode

        t = float(timestamp)
        try:
            messages = self.stream.feed(topic, encode(record), t)
        except (ValueError, KeyError, TypeError, IndexError) as exc:
            messages = self.stream.unreadable(topic, t, exc)
        self.server.offer(messages, t)
