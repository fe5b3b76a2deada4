"""The figures' layout: a learner whose label lists many settings (``--set``) still gets
a laid-out figure, its legend line wrapped, no matplotlib warning."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from cmarlcd.reports.figures import LEGEND_WIDTH, environment_curves

LONG = (
    "Deep CMARL-CD (critic_bootstrap='greedy', critic_fit='imitation', critic_form='degrees', "
    "expectile=0.5, gamma=0.99, return_lambda=0.9, target_every=500, temperature_end=0.01, "
    "temperature_steps=50000, train_every=50, update='critic')"
)


def test_a_long_label_is_wrapped_without_a_layout_warning(tmp_path: Path) -> None:
    runs = np.zeros((2, 3, 3))
    runs[:, :, 0] = [0, 1, 2]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = environment_curves(
            {LONG: runs, "random policy": runs[:1]}, "random policy", "curves",
            tmp_path / "curves.png", unit="steps",
        )  # fmt: skip
    assert path.stat().st_size > 0
    assert len(LONG) > 3 * LEGEND_WIDTH
