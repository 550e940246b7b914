"""Policies compared in the environment: episodes, a table and the error-travel trade-off.

Every policy plays the same episodes (episode k is reset with seed ``seed + k``: the same
noise, and on random sites the same site), so the comparison is paired: against a baseline,
:func:`paired_differences` gives each policy's mean difference per episode with its
confidence interval (Student's t over the episodes' differences, paired by seed).
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from scipy import stats

from twin.envs.campaign_env import CpsCampaignEnv
from twin.envs.policies import Policy, policy_for
from twin.report.figures import save_figure
from twin.scenario.schema import Scenario

__all__ = [
    "METRICS",
    "Episode",
    "PairedDifference",
    "PolicySummary",
    "paired_difference",
    "paired_differences",
    "play_episode",
    "play_episodes",
    "summarise",
    "tradeoff_figure",
    "write_differences",
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
        reward: the episode's return (the environment's reward summed over its steps).
        true_error_mm: the mean true world-frame camera error over all the site's cameras,
            a camera not calibrated counting the environment's ``uncalibrated_error_mm``,
            mm (what ``reward_mode="truth"`` gives, negated).
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
    reward: float = math.nan
    true_error_mm: float = math.nan

    @property
    def mean_camera_error_mm(self) -> float:
        """The mean of the calibrated cameras' errors, mm (NaN when none was)."""
        values = list(self.camera_errors_mm.values())
        return float(np.mean(values)) if values else math.nan


def play_episode(
    env: CpsCampaignEnv, policy: str | Policy, seed: int
) -> tuple[int, dict[str, Any]]:
    """Play one episode of ``policy`` (a name of :func:`policy_for` or a policy) from
    ``reset(seed=seed)``: (steps, the last info)."""
    steps, info, _ = _play(env, policy_for(policy) if isinstance(policy, str) else policy, seed)
    return steps, info


def _play(env: CpsCampaignEnv, policy: Policy, seed: int) -> tuple[int, dict[str, Any], float]:
    """One episode: (steps, the last info, the return)."""
    obs, info = env.reset(seed=seed)
    actor = policy(env, seed)
    steps, total = 0, 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(actor(obs, info))
        steps += 1
        total += float(reward)
        if terminated or truncated:
            return steps, info, total


def play_episodes(
    scenario: Scenario | None,
    policies: Sequence[str] | Mapping[str, Policy],
    episodes: int,
    seed: int = 0,
    progress: Callable[[str, int], None] | None = None,
    **env_kwargs: object,
) -> list[Episode]:
    """Play ``episodes`` episodes of each policy.

    Args:
        scenario: the site; None: a random site each episode (from its seed).
        policies: the policies' names (:data:`twin.envs.policies.POLICIES`) or saved
            models' paths (:func:`twin.envs.policies.policy_for`), or the policies by name.
        episodes: episodes per policy. seed: episode k's reset seed is ``seed + k``.
        progress: called with (policy, episodes done) after each episode.
        env_kwargs: further arguments of :class:`CpsCampaignEnv`.

    Raises:
        ValueError: an unknown policy, a model that cannot be loaded or does not fit the
            environment, or a bad environment argument.
    """
    resolved = (  # an unknown name fails before any episode
        dict(policies)
        if isinstance(policies, Mapping)
        else {name: policy_for(name) for name in policies}
    )
    env = CpsCampaignEnv(scenario, **env_kwargs)  # type: ignore[arg-type]
    out = []
    try:
        for name in resolved:
            for k in range(episodes):
                start = time.perf_counter()
                steps, info, total = _play(env, resolved[name], seed + k)
                assert env.scenario is not None
                errors = dict(info["camera_errors_mm"])
                cameras = len(env.scenario.cameras)
                missing = (cameras - len(errors)) * env.uncalibrated_error_mm
                out.append(
                    Episode(
                        name,
                        k,
                        seed + k,
                        env.scenario.name,
                        errors,
                        cameras,
                        info["parent_error_mm"],
                        info["distance_m"],
                        info["time_s"],
                        steps,
                        time.perf_counter() - start,
                        total,
                        (sum(errors.values()) + missing) / cameras if cameras else 0.0,
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


METRICS = ("true_error_mm", "mean_camera_error_mm", "reward", "distance_m", "time_s")
"""What :func:`paired_differences` compares by default (:class:`Episode`'s names)."""


@dataclass(frozen=True)
class PairedDifference:
    """A policy's mean difference from a baseline over the episodes both played (same seed).

    Attributes:
        policy, baseline: their names. metric: an :class:`Episode` attribute (its unit).
        pairs: the episodes compared (those where both values are defined).
        policy_mean, baseline_mean: each one's mean over those episodes.
        mean: the mean of ``policy - baseline``. low, high: its confidence interval
            (NaN with fewer than two pairs). confidence: the interval's level.
    """

    policy: str
    baseline: str
    metric: str
    pairs: int
    policy_mean: float
    baseline_mean: float
    mean: float
    low: float
    high: float
    confidence: float


def paired_difference(
    values: Sequence[float], baseline: Sequence[float], confidence: float = 0.95
) -> tuple[int, float, float, float]:
    """The mean of ``values - baseline`` (pairs where both are finite) and its Student's t
    confidence interval: (pairs, mean, low, high); the interval is NaN with fewer than two
    pairs.

    Raises:
        ValueError: the sequences differ in length, or ``confidence`` is not in (0, 1).
    """
    a, b = np.asarray(values, dtype=float), np.asarray(baseline, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(
            f"paired values: expected two sequences of one length: {a.shape}, {b.shape}"
        )
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    d = (a - b)[np.isfinite(a) & np.isfinite(b)]
    n = int(d.size)
    if n == 0:
        return 0, math.nan, math.nan, math.nan
    mean = float(np.mean(d))
    if n < 2:
        return n, mean, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1)) * float(np.std(d, ddof=1)) / math.sqrt(n)
    return n, mean, mean - half, mean + half


def paired_differences(
    episodes: Sequence[Episode],
    baseline: str,
    metrics: Sequence[str] = METRICS,
    confidence: float = 0.95,
) -> list[PairedDifference]:
    """Each policy other than ``baseline`` against it, per metric, episodes paired by seed
    (see :func:`paired_difference`), in the order the policies played.

    Raises:
        ValueError: ``baseline`` played no episode.
    """
    base = {e.seed: e for e in episodes if e.policy == baseline}
    if not base:
        raise ValueError(f"baseline {baseline!r} played no episode")
    out = []
    for name in dict.fromkeys(e.policy for e in episodes):
        if name == baseline:
            continue
        mine = [e for e in episodes if e.policy == name and e.seed in base]
        for metric in metrics:
            a = [float(getattr(e, metric)) for e in mine]
            b = [float(getattr(base[e.seed], metric)) for e in mine]
            both = [(x, y) for x, y in zip(a, b, strict=True) if math.isfinite(x + y)]
            n, mean, low, high = paired_difference(a, b, confidence)
            out.append(
                PairedDifference(
                    name,
                    baseline,
                    metric,
                    n,
                    float(np.mean([x for x, _ in both])) if both else math.nan,
                    float(np.mean([y for _, y in both])) if both else math.nan,
                    mean,
                    low,
                    high,
                    confidence,
                )
            )
    return out


def write_differences(differences: Sequence[PairedDifference], path: Path) -> Path:
    """A CSV of the paired differences, a row each."""
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        fields = list(PairedDifference.__dataclass_fields__)
        writer.writerow(fields)
        for d in differences:
            row = asdict(d)
            writer.writerow([row[k] for k in fields])
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
