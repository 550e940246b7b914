"""The campaign's abort: the group cannot go on."""

from __future__ import annotations


class CampaignAborted(RuntimeError):
    """The group cannot go on (CPS lost both children, or no leg can be planned)."""
