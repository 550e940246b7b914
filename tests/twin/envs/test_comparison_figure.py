"""The policies' trade-off figure, with and without an episode that calibrated a camera."""

from __future__ import annotations

import warnings
from dataclasses import fields

from twin.envs.comparison import Episode, tradeoff_figure


def _episode(policy: str, errors: dict[str, float]) -> Episode:
    values = {f.name: 0 for f in fields(Episode)}
    values.update(policy=policy, camera_errors_mm=errors, distance_m=10.0)
    return Episode(**values)


def test_a_comparison_where_no_episode_calibrated_draws_without_a_legend_warning(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for episodes in ([_episode("random", {})], [_episode("greedy", {"cam1": 12.0})]):
            path = tradeoff_figure(episodes, tmp_path / "tradeoff.png", "t")
            assert path.stat().st_size > 0
