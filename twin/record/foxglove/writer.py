"""Foxglove's messages into an MCAP writer: each message encoded by the SDK (protobuf),
its schema the SDK's own (``foxglove.FrameTransforms``...), one channel per topic."""

from __future__ import annotations

from typing import Any

from mcap.records import Channel
from mcap.writer import Writer

from twin.record.mcap_log import FOXGLOVE_ENCODING as MESSAGE_ENCODING
from twin.record.mcap_log import add_message


def is_foxglove_channel(channel: Channel) -> bool:
    """Whether a channel of a log carries Foxglove's messages (not the run's records)."""
    return channel.message_encoding == MESSAGE_ENCODING


class FoxgloveChannels:
    """Writes Foxglove messages (:mod:`foxglove.messages`) with ``writer``, registering each
    schema and channel the first time it is used.

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
                message_encoding=MESSAGE_ENCODING,
                schema_id=self._schemas[schema.name],
            )
        return self._channels[topic]
