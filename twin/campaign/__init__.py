"""The calibration campaign, written only against the hardware-abstraction interface.

Decisions and their execution are apart:

- :mod:`.strategy`: the interface of the campaign's decisions (:class:`Strategy`: the
  reference cameras, the next visit, the next CPS leg, a camera's data stops) and what a
  strategy sees (:class:`CampaignView`); :mod:`.paper_strategy`: the paper's
  (:class:`PaperStrategy`); :mod:`.strategies`: the strategies by name.
- :mod:`.procedure`: :class:`Campaign`, which orders the stages, asks its strategy and
  executes the answers: :mod:`.travel` (CPS legs: the children's and the parent's moves,
  placing and checking children, the parent's fix), :mod:`.collection` (a camera's data
  and its calibration), :mod:`.shooting` (a child's corner cubes measured, with retries).
- :mod:`.bounds`: how long each of the campaign's loops may go on (from the scenario)
  before it ends with the failure ``no_progress`` (:class:`NoProgress`).
- :mod:`.journal`: the campaign's records, counts and progress; :mod:`.records`: the
  records; :mod:`.log_results`: a run's results from its log.
- :mod:`.plan`: the geometry the strategies decide with: the route, the legs, the
  formation, the view stops, clearance and prisms hidden by their own assembly.
- :mod:`.check`: ``twin check``: the campaign's steps with a few stops per camera, a
  chi-square test of each camera against its calibration, and a re-pose of those that
  moved.

This package imports ``twin.hal``, ``twin.localization``, ``twin.instruments`` (the
instrument's measurement models and errors), ``twin.scenario`` (the plan and the map) and
``calib``; never a backend (``twin.sim``, ``twin.drivers``), and it does not read the twin's
simulated noise or faults from the scenario. The strategies import no device at all. Tests
enforce it.
"""

from twin.campaign.journal import CampaignOutcome, Progress
from twin.campaign.paper_strategy import PaperStrategy
from twin.campaign.procedure import Campaign
from twin.campaign.strategies import DEFAULT_STRATEGY, STRATEGIES, strategy_named
from twin.campaign.strategy import CampaignView, Strategy
from twin.campaign.travel import CampaignAborted, NoProgress

__all__ = [
    "DEFAULT_STRATEGY",
    "STRATEGIES",
    "Campaign",
    "CampaignAborted",
    "CampaignOutcome",
    "CampaignView",
    "NoProgress",
    "PaperStrategy",
    "Progress",
    "Strategy",
    "strategy_named",
]
