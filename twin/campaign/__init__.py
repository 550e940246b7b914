"""The calibration campaign, written only against the hardware-abstraction interface.

- :mod:`.procedure`: :class:`Campaign`, the paper's procedure (reference data sets, CPS
  travel, calibration stations, visits in order), with faults counted, not fatal.
- :mod:`.plan`, :mod:`.route`, :mod:`.geometry`: where the robots go, on the map.
- :mod:`.shooting`: measuring a child's corner cubes, with retries.
- :mod:`.records`: what the campaign records beside the devices' readings.

This package imports ``twin.hal``, ``twin.localization``, ``twin.instruments`` (the
instrument's measurement models and errors), ``twin.scenario`` (the plan and the map) and
``calib``; never a backend (``twin.sim``, ``twin.drivers``). A test enforces it.
"""

from twin.campaign.procedure import Campaign, CampaignAborted, CampaignOutcome, Progress

__all__ = ["Campaign", "CampaignAborted", "CampaignOutcome", "Progress"]
