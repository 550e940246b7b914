"""LED detection: sub-pixel LED positions from a switched sequence of camera frames."""

from calib.detection.sequence import SwitchingSequence

__all__ = ["SwitchingSequence"]
