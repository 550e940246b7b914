"""Policies compared in the environment: episodes, a table and the error-travel trade-off.

Every policy plays the same episodes (episode k is reset with seed ``seed + k``: the same
noise, and on random sites the same site), so the comparison is paired.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from twin.envs.campaign_env import CpsCampaignEnv
from twin.envs.policies import policy_named
from twin.report.figures import save_figure
from twin.scenario.schema import Scenario

__all__ = [
    "Episode",
    "PolicySummary",
    "play_episode",
    "play_episodes",
    "summarise",
    "tradeoff_figure",
]


@dataclass(frozen=True)
class Episode:
    """One episode of a policy.

    Attributes:
        policy: its name. episode: its index. seed: its reset seed. site: the site's name.
        camera_errors_mm: the true world-frame position error of each camera's delivered
            calibration, mm, by camera (cameras not calibrated are absent).
        cameras: the site's cameras. parent_error_mm: the parent's error at its last fix.
        distance_m: the parent's travel. time_s: the campaign's time. steps: decisions.
        wall_s: the episode's wall-clock time, s.
    """

    policy: str
    episode: int
    seed: int
    site: str
    camera_errors_mm: dict[str, float]
    cameras: int
    parent_error_mm: float
    distance_m: float
    time_s: float
    steps: int
    wall_s: float

    @property
    def mean_camera_error_mm(self) -> float:
        """The mean of the calibrated cameras' errors, mm (NaN when none was)."""
        values = list(self.camera_errors_mm.values())
        return float(np.mean(values)) if values else math.nan


def play_episode(env: CpsCampaignEnv, policy: str, seed: int) -> tuple[int, dict[str, Any]]:
    """Play one episode of ``policy`` from ``reset(seed=seed)``: (steps, the last info)."""
    obs, info = env.reset(seed=seed)
    actor = policy_named(policy)(env, seed)
    steps = 0
    while True:
        obs, _, terminated, truncated, info = env.step(actor(obs, info))
        steps += 1
        if terminated or truncated:
            return steps, info


def play_episodes(
    scenario: Scenario | None,
    policies: Sequence[str],
    episodes: int,
    seed: int = 0,
    progress: Callable[[str, int], None] | None = None,
    **env_kwargs: object,
) -> list[Episode]:
    """Play ``episodes`` episodes of each policy.

    Args:
        scenario: the site; None: a random site each episode (from its seed).
        policies: the policies' names (:data:`twin.envs.policies.POLICIES`).
        episodes: episodes per policy. seed: episode k's reset seed is ``seed + k``.
        progress: called with (policy, episodes done) after each episode.
        env_kwargs: further arguments of :class:`CpsCampaignEnv`.

    Raises:
        ValueError: an unknown policy, or a bad environment argument.
    """
    for name in policies:
        policy_named(name)  # an unknown name fails before any episode
    env = CpsCampaignEnv(scenario, **env_kwargs)  # type: ignore[arg-type]
    out = []
    try:
        for name in policies:
            for k in range(episodes):
                start = time.perf_counter()
                steps, info = play_episode(env, name, seed + k)
                assert env.scenario is not None
                out.append(
                    Episode(
                        name,
                        k,
                        seed + k,
                        env.scenario.name,
                        dict(info["camera_errors_mm"]),
                        len(env.scenario.cameras),
                        info["parent_error_mm"],
                        info["distance_m"],
                        info["time_s"],
                        steps,
                        time.perf_counter() - start,
                    )
                )
                if progress is not None:
                    progress(name, k + 1)
    finally:
        env.close()
    return out


@dataclass(frozen=True)
class PolicySummary:
    """A policy over its episodes (errors over every calibrated camera of every episode).

    Attributes:
        policy: its name. episodes: how many.
        camera_median_mm, camera_p90_mm: the cameras' world-frame errors, mm.
        calibrated: the fraction of the cameras calibrated.
        distance_m, time_s: the mean travel and campaign time.
        parent_median_mm: the parent's final error, median.
        steps_per_s: the environment's decisions per second of wall-clock time.
    """

    policy: str
    episodes: int
    camera_median_mm: float
    camera_p90_mm: float
    calibrated: float
    distance_m: float
    time_s: float
    parent_median_mm: float
    steps_per_s: float


def summarise(episodes: Sequence[Episode]) -> list[PolicySummary]:
    """A summary per policy, in the order the policies played."""
    out = []
    for name in dict.fromkeys(e.policy for e in episodes):
        mine = [e for e in episodes if e.policy == name]
        errors = [v for e in mine for v in e.camera_errors_mm.values()]
        has = bool(errors)
        out.append(
            PolicySummary(
                name,
                len(mine),
                float(np.median(errors)) if has else math.nan,
                float(np.percentile(errors, 90)) if has else math.nan,
                len(errors) / max(1, sum(e.cameras for e in mine)),
                float(np.mean([e.distance_m for e in mine])),
                float(np.mean([e.time_s for e in mine])),
                float(np.median([e.parent_error_mm for e in mine])),
                sum(e.steps for e in mine) / max(1e-9, sum(e.wall_s for e in mine)),
            )
        )
    return out


def write_episodes(episodes: Sequence[Episode], path: Path) -> Path:
    """A CSV of the episodes, a row each (the cameras' errors as ``error_<camera>_mm``)."""
    cameras = sorted({c for e in episodes for c in e.camera_errors_mm})
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        fields = [k for k in asdict(episodes[0]) if k != "camera_errors_mm"] if episodes else []
        writer.writerow([*fields, "mean_camera_error_mm", *(f"error_{c}_mm" for c in cameras)])
        for e in episodes:
            row = asdict(e)
            writer.writerow(
                [row[k] for k in fields]
                + [e.mean_camera_error_mm]
                + [e.camera_errors_mm.get(c, "") for c in cameras]
            )
    return path


def tradeoff_figure(episodes: Sequence[Episode], path: Path, title: str) -> Path:
    """The trade-off: each episode's mean camera error against its travel, one colour per
    policy, with each policy's medians as a large marker."""
    fig = Figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    for i, name in enumerate(dict.fromkeys(e.policy for e in episodes)):
        mine = [e for e in episodes if e.policy == name and e.camera_errors_mm]
        if not mine:
            continue
        colour = f"C{i}"
        d = np.array([e.distance_m for e in mine])
        err = np.array([e.mean_camera_error_mm for e in mine])
        ax.scatter(d, err, s=12, alpha=0.5, color=colour, label=f"{name} ({len(mine)})")
        ax.scatter(
            [np.median(d)],
            [np.median(err)],
            s=140,
            marker="*",
            color=colour,
            edgecolor="black",
            zorder=5,
        )
    ax.set_xlabel("parent's travel [m]")
    ax.set_ylabel("mean world-frame camera error of an episode [mm]")
    ax.set_title(title)
    if ax.collections:
        ax.set_yscale("log")
        ax.grid(True, which="both", color="0.9")
        ax.legend(title="policy (episodes); star: medians", fontsize=8)
    else:
        ax.text(0.5, 0.5, "no episode calibrated a camera", ha="center", transform=ax.transAxes)
    return save_figure(fig, path)
