"""A one-line live status of a campaign (``twin run``, ``twin check``): stage, robot,
camera, points, calibrations, elapsed time."""

from __future__ import annotations

import time
from collections.abc import Mapping

from rich.live import Live
from rich.markup import escape
from rich.table import Table

from twin.campaign import Progress


class LiveStatus:
    """Called with each :class:`twin.campaign.Progress`; updates ``live``.

    Args:
        live: the rich display. stage_names: words shown for some stages' names.
        calibrated: show how many cameras were calibrated.
    """

    def __init__(
        self, live: Live, stage_names: Mapping[str, str] | None = None, calibrated: bool = True
    ) -> None:
        self.live = live
        self.t0 = time.perf_counter()
        self.stage_names = dict(stage_names or {})
        self.calibrated = calibrated

    def __call__(self, p: Progress) -> None:
        grid = Table.grid(padding=(0, 2))
        cells = [
            f"[bold]{escape(self.stage_names.get(p.stage, p.stage))}[/bold]",
            f"robot {escape(p.robot or '-')}",
            f"camera {escape(p.camera or '-')}",
            f"points {p.points}",
        ]
        if self.calibrated:
            cells.append(f"calibrated {p.calibrated}")
        grid.add_row(*cells, f"{time.perf_counter() - self.t0:6.1f} s")
        self.live.update(grid)
