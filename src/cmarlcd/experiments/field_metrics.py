"""The field's two figures of a learning curve (EPyMARL's protocol: Papoudakis et al.,
"Benchmarking multi-agent deep reinforcement learning algorithms in cooperative tasks",
NeurIPS 2021 Datasets and Benchmarks), computed from the greedy evaluations of several
seeds at the same points of learning:

* the **maximum return**: the evaluation point whose mean over seeds is highest (the
  first such point on a tie), that mean, and the interval of the seeds' returns there;
* the **average return**: the mean over every evaluation point of the mean over seeds (it
  rewards learning fast as well as learning well), and the interval of the seeds' own
  averages over the points.

[choice] Each interval is Student's t interval of the mean over the seeds
(:data:`CONFIDENCE` 95 %): the seeds are the independent samples; the points of one seed's
curve are not. With one seed, or seeds that all agree, it is the value itself.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from cmarlcd.errors import require

#: The intervals' confidence level ([choice]).
CONFIDENCE = 0.95


@dataclass(frozen=True)
class FieldMetrics:
    """The two figures of one task and learner (``*_low``/``*_high``: the interval)."""

    max_return: float
    max_return_low: float
    max_return_high: float
    max_return_at: int
    """The learning (steps or episodes, as the curve counts) of the maximum's point."""
    average_return: float
    average_return_low: float
    average_return_high: float
    seeds: int
    points: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def mean_interval(values: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Student's t interval of the mean of ``values`` (independent samples); the mean
    itself for one value or values that all agree."""
    from scipy import stats  # imported when used: it slows every command's start

    mean = float(np.mean(values))
    if len(values) < 2:
        return mean, mean
    se = float(np.std(values, ddof=1)) / math.sqrt(len(values))
    if se == 0.0:
        return mean, mean
    half = float(stats.t.ppf(0.5 + confidence / 2, len(values) - 1)) * se
    return mean - half, mean + half


def field_metrics(
    learning: Sequence[int], returns: np.ndarray, confidence: float = CONFIDENCE
) -> FieldMetrics:
    """The maximum and the average return of the curves ``returns`` (seeds, points): each
    seed's greedy return at the points of ``learning`` (the same points for every seed)."""
    returns = np.asarray(returns, dtype=float)
    require(returns.ndim == 2, "returns", f"must be (seeds, points) (got shape {returns.shape})")
    seeds, points = returns.shape
    require(seeds >= 1 and points >= 1, "returns", "needs at least one seed and one point")
    require(
        len(learning) == points,
        "learning",
        f"must give one point per column of returns ({points}; got {len(learning)})",
    )
    require(bool(np.isfinite(returns).all()), "returns", "must be finite")
    require(0 < confidence < 1, "confidence", f"must be in (0, 1) (got {confidence})")
    means = returns.mean(axis=0)
    best = int(np.argmax(means))  # the first point on a tie
    best_low, best_high = mean_interval(returns[:, best], confidence)
    averages = returns.mean(axis=1)  # each seed's own average over the points
    average_low, average_high = mean_interval(averages, confidence)
    return FieldMetrics(
        max_return=float(means[best]),
        max_return_low=best_low,
        max_return_high=best_high,
        max_return_at=int(learning[best]),
        average_return=float(averages.mean()),
        average_return_low=average_low,
        average_return_high=average_high,
        seeds=seeds,
        points=points,
    )
