"""The field's maximum and average return, from hand-made curves."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.experiments.field_metrics import field_metrics, mean_interval

#: Three seeds evaluated at four points (50k, 100k, 150k, 200k steps).
LEARNING = [50_000, 100_000, 150_000, 200_000]
CURVES = np.array(
    [
        [0.0, 2.0, 5.0, 4.0],
        [1.0, 3.0, 6.0, 8.0],
        [2.0, 4.0, 7.0, 6.0],
    ]
)
#: Student's t quantile t_{0.975, 2}, from a printed table.
T_975_2 = 4.303


def test_the_maximum_is_the_point_whose_mean_over_seeds_is_highest() -> None:
    """Means over seeds: 1, 3, 6, 6: the tie goes to the first point, 150k, mean 6; the
    seeds there are 5, 6, 7 (sample SD 1, SE 1/√3)."""
    got = field_metrics(LEARNING, CURVES)
    assert got.max_return == 6.0 and got.max_return_at == 150_000
    half = T_975_2 / math.sqrt(3)
    assert got.max_return_low == pytest.approx(6.0 - half, abs=1e-3)
    assert got.max_return_high == pytest.approx(6.0 + half, abs=1e-3)
    assert (got.seeds, got.points) == (3, 4)


def test_the_average_is_over_every_point_and_its_interval_over_the_seeds_averages() -> None:
    """Seeds' averages over the points: 11/4, 18/4, 19/4 (mean 4, sample SD √1.1667)."""
    got = field_metrics(LEARNING, CURVES)
    assert got.average_return == pytest.approx(4.0)
    averages = [2.75, 4.5, 4.75]
    sd = math.sqrt(sum((a - 4.0) ** 2 for a in averages) / 2)
    half = T_975_2 * sd / math.sqrt(3)
    assert got.average_return_low == pytest.approx(4.0 - half, abs=1e-3)
    assert got.average_return_high == pytest.approx(4.0 + half, abs=1e-3)


def test_one_seed_or_agreeing_seeds_have_the_value_as_their_interval() -> None:
    one = field_metrics(LEARNING, CURVES[:1])
    assert one.max_return == one.max_return_low == one.max_return_high == 5.0
    assert mean_interval(np.array([2.0, 2.0, 2.0])) == (2.0, 2.0)


@pytest.mark.parametrize(
    ("learning", "returns", "parameter"),
    [
        (LEARNING, CURVES[0], "returns"),
        (LEARNING[:3], CURVES, "learning"),
        (LEARNING, np.where(CURVES > 7, np.nan, CURVES), "returns"),
        ([], np.zeros((2, 0)), "returns"),
    ],
)
def test_bad_curves_are_refused(learning, returns, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        field_metrics(learning, returns)
    assert info.value.parameter == parameter
