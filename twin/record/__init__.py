"""The run log: every record of a campaign, written as it arrives, readable after a kill.

- :mod:`.codec`: :func:`encode` a record (a frozen dataclass of :mod:`twin.hal.readings`)
  as plain JSON values and :func:`decode` it back.
- :mod:`.mcap_log`: :class:`McapRecorder`, a :class:`~twin.hal.recording.Recorder` writing
  one JSON message per record to an MCAP file, flushed every few messages; :func:`read_log`
  reads it back, whole or cut short by a killed writer, as :class:`LogContents`.

Timestamps are seconds on the rig's clock; the records keep their SI units.
"""

from twin.record.codec import decode, encode
from twin.record.mcap_log import LogContents, LogMessage, McapRecorder, read_log

__all__ = ["LogContents", "LogMessage", "McapRecorder", "decode", "encode", "read_log"]
