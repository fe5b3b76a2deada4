"""TOST against hand-computed cases (Student's t quantiles from printed tables)."""

from __future__ import annotations

import pytest

from cmarlcd import ConfigError
from cmarlcd.experiments.equivalence import paired_tost, tost

REFERENCE = [0.0, 1.0, 2.0, 3.0, 4.0]  # mean 2, variance 2.5
CANDIDATE = [1.0, 2.0, 3.0, 4.0, 5.0]  # mean 3, variance 2.5


def test_tost_against_a_hand_computed_case() -> None:
    """d = 1; se = sqrt(2.5/5 + 2.5/5) = 1; Welch's df = 1 / (2 · 0.5² / 4) = 8;
    t(0.95, 8) = 1.860 (table): interval [-0.860, 2.860]. Margin 3: inside, and the
    larger one-sided p is P(T8 <= (1 - 3)/1) = 0.0403 (table). Margin 2: the interval
    crosses 2, p = P(T8 <= -1) = 0.173."""
    wide = tost(REFERENCE, CANDIDATE, margin=3.0)
    assert wide.difference == pytest.approx(1.0)
    assert (wide.low, wide.high) == pytest.approx((1 - 1.860, 1 + 1.860), abs=1e-3)
    assert wide.p_value == pytest.approx(0.0403, abs=1e-4)
    assert wide.equivalent
    narrow = tost(REFERENCE, CANDIDATE, margin=2.0)
    assert narrow.p_value == pytest.approx(0.173, abs=1e-3)
    assert not narrow.equivalent


def test_tost_is_symmetric_and_needs_runs() -> None:
    forth, back = tost(REFERENCE, CANDIDATE, 3.0), tost(CANDIDATE, REFERENCE, 3.0)
    assert back.difference == -forth.difference and back.p_value == pytest.approx(forth.p_value)
    constant = tost([1.0, 1.0], [1.5, 1.5], margin=1.0)
    assert constant.equivalent and constant.p_value == 0.0
    for bad in ({"reference": [1.0]}, {"margin": 0.0}, {"alpha": 0.5}):
        args = {"reference": REFERENCE, "candidate": CANDIDATE, "margin": 1.0} | bad
        with pytest.raises(ConfigError):
            tost(**args)


def test_paired_tost_against_a_hand_computed_case() -> None:
    """Differences [-1, 0, 1, 2, 3] (each candidate against its own reference): mean 1,
    variance 2.5, se = sqrt(2.5 / 5) = 0.7071, df = 4, t(0.95, 4) = 2.132 (table):
    interval [-0.508, 2.508]. Margin 3: inside, p = P(T4 <= -2/0.7071 = -2.828), between
    0.02 and 0.025 (t(0.975, 4) = 2.776, t(0.98, 4) = 2.999). Margin 2: crosses 2. The
    same values unpaired (Welch) give a wider interval: the pairing is what it tests."""
    reference = [10.0, 20.0, 30.0, 40.0, 50.0]
    candidate = [9.0, 20.0, 31.0, 42.0, 53.0]
    wide = paired_tost(reference, candidate, margin=3.0)
    assert wide.difference == pytest.approx(1.0)
    assert (wide.low, wide.high) == pytest.approx((1 - 1.5076, 1 + 1.5076), abs=1e-3)
    assert 0.02 < wide.p_value < 0.025
    assert wide.equivalent
    assert not paired_tost(reference, candidate, margin=2.0).equivalent
    assert not tost(reference, candidate, margin=3.0).equivalent
    with pytest.raises(ConfigError):
        paired_tost(reference, candidate[:4], margin=3.0)
