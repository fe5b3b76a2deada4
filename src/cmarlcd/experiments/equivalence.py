"""Equivalence of two sets of runs by statistics: Schuirmann's two one-sided tests (TOST).

Where a change alters float rounding (the fused gradient step), runs follow other
trajectories and their numbers cannot be equal bit for bit; what can be shown is that
the new runs' mean lies within a margin, declared beforehand, of the old runs' mean.
TOST does that: with the difference ``d = mean(candidate) - mean(reference)``, its
standard error ``se`` (Welch: unequal variances) and ``t``, the ``1 - α`` quantile of
Student's t with Welch–Satterthwaite's degrees of freedom, the two are equivalent at
level ``α`` when ``[d - t·se, d + t·se]`` (the ``1 - 2α`` interval) lies inside
``(-margin, margin)``; the p-value is the larger of the two one-sided tests'.

Where each candidate value has a reference value of its own (the two sides of one match:
:func:`paired_tost`), the test is on the differences, one per pair: their mean, its
standard error and Student's t with ``n - 1`` degrees of freedom.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cmarlcd.errors import require

#: [choice] The level of the two one-sided tests (each at α: a 90 % interval).
ALPHA = 0.05


@dataclass(frozen=True)
class Equivalence:
    """The outcome of :func:`tost` for one cell."""

    reference_mean: float
    candidate_mean: float
    difference: float
    low: float
    """The ``1 - 2α`` interval of the difference: ``low`` ..."""
    high: float
    """... ``high``."""
    margin: float
    p_value: float
    reference_runs: int
    candidate_runs: int

    @property
    def equivalent(self) -> bool:
        """Whether the interval lies inside ``(-margin, margin)``."""
        return -self.margin < self.low and self.high < self.margin

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "equivalent": self.equivalent}


def tost(
    reference: Sequence[float], candidate: Sequence[float], margin: float, alpha: float = ALPHA
) -> Equivalence:
    """Schuirmann's two one-sided Welch tests of ``|mean(candidate) - mean(reference)| <
    margin`` (see the module)."""
    ref, new = np.asarray(reference, float), np.asarray(candidate, float)
    require(len(ref) >= 2 and len(new) >= 2, "runs", "TOST needs at least 2 runs a side")
    va, vb = ref.var(ddof=1) / len(ref), new.var(ddof=1) / len(new)
    se = math.sqrt(va + vb)
    df = (va + vb) ** 2 / (va**2 / (len(ref) - 1) + vb**2 / (len(new) - 1)) if se else 0.0
    return _two_one_sided(ref, new, float(new.mean() - ref.mean()), se, df, margin, alpha)


def paired_tost(
    reference: Sequence[float], candidate: Sequence[float], margin: float, alpha: float = ALPHA
) -> Equivalence:
    """TOST of ``|mean(candidate - reference)| < margin`` where ``candidate[k]`` and
    ``reference[k]`` come from one trial (see the module): the differences' mean, its
    ``1 - 2α`` interval from Student's t with ``n - 1`` degrees of freedom."""
    ref, new = np.asarray(reference, float), np.asarray(candidate, float)
    require(len(ref) == len(new), "runs", "a paired test needs one reference value a run")
    require(len(ref) >= 2, "runs", "TOST needs at least 2 runs")
    differences = new - ref
    se = float(differences.std(ddof=1)) / math.sqrt(len(differences))
    return _two_one_sided(
        ref, new, float(differences.mean()), se, len(differences) - 1, margin, alpha
    )


def _two_one_sided(
    ref: np.ndarray,
    new: np.ndarray,
    difference: float,
    se: float,
    df: float,
    margin: float,
    alpha: float,
) -> Equivalence:
    """The two one-sided t tests of ``difference`` (standard error ``se``, ``df`` degrees
    of freedom) against ``±margin``, and the ``1 - 2α`` interval."""
    from scipy import stats  # imported when used: it slows every command's start

    require(margin > 0, "margin", f"must be > 0 (got {margin})")
    require(0 < alpha < 0.5, "alpha", f"must be in (0, 0.5) (got {alpha})")
    if se == 0.0:  # constant: the difference is known exactly
        low = high = difference
        p_value = 0.0 if abs(difference) < margin else 1.0
    else:
        half = float(stats.t.ppf(1 - alpha, df)) * se
        low, high = difference - half, difference + half
        below = float(stats.t.sf((difference + margin) / se, df))  # H0: d <= -margin
        above = float(stats.t.cdf((difference - margin) / se, df))  # H0: d >= margin
        p_value = max(below, above)
    return Equivalence(
        float(ref.mean()), float(new.mean()), difference, low, high, float(margin),
        p_value, len(ref), len(new),
    )  # fmt: skip
