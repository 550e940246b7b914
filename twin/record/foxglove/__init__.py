"""Foxglove's own messages derived from a run's records, for Foxglove's 3D, log and plot
panels: written into the run's log beside the records (:class:`twin.record.McapRecorder`
with a :class:`FoxgloveStream`), or from an older log by ``twin replay --foxglove``.

- :mod:`.convert`: timestamps, poses, quaternions and colours as Foxglove's messages.
- :mod:`.frames`: ``foxglove.FrameTransforms`` of W, the robots, the instrument and the
  cameras (as built and as calibrated).
- :mod:`.scene`: ``foxglove.SceneUpdate`` entities: the site, the route and stations, the
  cameras' view frustums, the LED points, the parent's covariance, the lines of sight.
- :mod:`.images`: a camera's ``foxglove.CameraCalibration``, ``foxglove.CompressedImage``
  and ``foxglove.ImageAnnotations`` (the LEDs found, the measured points projected).
- :mod:`.stream`: :class:`FoxgloveStream`, the records in, the messages out (topics in
  :data:`TOPICS`), the same for a run and for a replay.

Timestamps are the campaign's clock (s since the run's start), as the records'.
"""

from twin.record.foxglove.stream import TOPICS, FoxgloveStream

__all__ = ["TOPICS", "FoxgloveStream"]
