"""The process's tables of sites (:class:`twin.envs.stand_site.StandSite`): one per site
and move layout, read from its file or made on first use, the last used kept, one dropped
saved (:mod:`twin.envs.stand_cache`), and every one saved when the process ends."""

from __future__ import annotations

import atexit
import weakref
from collections import OrderedDict

from twin.envs.moves import MoveLayout
from twin.envs.stand_site import StandSite
from twin.scenario.schema import Scenario

SITES = 8
"""Sites whose tables a process keeps (the least recently used is dropped)."""

_SITES: OrderedDict[tuple[str, MoveLayout], StandSite] = OrderedDict()
_LIVE: weakref.WeakValueDictionary[tuple[str, MoveLayout], StandSite] = (
    weakref.WeakValueDictionary()
)  # every table a planner still holds, kept or not


def site_for(scenario: Scenario, layout: MoveLayout) -> StandSite:
    """The process's table of a site (read from its file or made on first use). The
    process keeps the :data:`SITES` used last; one dropped is saved, and lives on while a
    planner holds it (as many tables as the episodes' sites are open at once)."""
    key = (scenario.model_dump_json(), layout)
    site = _SITES.get(key) or _LIVE.get(key)
    if site is None:
        site = _LIVE[key] = StandSite(scenario, layout)
    _SITES[key] = site
    _SITES.move_to_end(key)
    while len(_SITES) > SITES:
        _SITES.popitem(last=False)[1].save()
    return site


@atexit.register
def _save_sites() -> None:
    for site in {id(s): s for s in (*_SITES.values(), *_LIVE.values())}.values():
        site.save()


def clear_sites() -> None:
    """Save and forget every site's table (a planner that holds one goes on with it)."""
    sites = {id(s): s for s in (*_SITES.values(), *_LIVE.values())}
    _SITES.clear()
    _LIVE.clear()
    for site in sites.values():
        site.close()
