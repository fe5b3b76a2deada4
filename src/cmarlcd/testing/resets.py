"""What a comparison of two games' reset distributions found
(:mod:`cmarlcd.testing.foraging`, :mod:`cmarlcd.testing.spread`)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class ResetReport:
    """Each statistic's two-sample p-value over ``resets`` resets of each game."""

    task: str
    resets: int
    p_values: dict[str, float]
    alpha: float

    @property
    def smallest(self) -> float:
        return min(self.p_values.values())

    @property
    def equal(self) -> bool:
        """No statistic differs at ``alpha``, Bonferroni-corrected over the statistics."""
        return self.smallest >= self.alpha / len(self.p_values)
