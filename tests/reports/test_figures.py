"""The figures' layout: a learner whose label lists many settings (``--set``) still gets
a laid-out figure, its legend line wrapped, no matplotlib warning."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from cmarlcd.reports.figures import (
    LEGEND_WIDTH,
    dsn_policy_grid,
    environment_curves,
    learning_curves,
    scaling_curves,
)

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


def _dsn_curves(path: Path) -> Path:
    runs = np.zeros((2, 3, 4))
    runs[:, :, 0] = [0, 1, 2]
    return learning_curves({LONG: runs, "VDN": runs}, path)


def _scaling(path: Path) -> Path:
    rows = np.array([[43, 1.0, 0.0, 19.6], [1753, 1.0, 0.0, -4.9]])
    return scaling_curves({LONG: rows, "VDN": rows}, f"scaling, {LONG}", path)


def _fig4(path: Path) -> Path:
    title = f"Fig. 4 — greedy joint action of {LONG}, L = 100,000, seed 0, run 0"
    return dsn_policy_grid(np.zeros((42, 12), dtype=int), title, path)


@pytest.mark.parametrize("draw", [_dsn_curves, _scaling, _fig4])
def test_every_figure_lays_out_a_learner_with_many_settings(draw, tmp_path: Path) -> None:
    """The DSN curves, the scaling figure and Fig. 4 title or label a learner by its
    settings too (a DSN run with --set warned of a layout it could not make)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = draw(tmp_path / "figure.png")
    assert path.stat().st_size > 0
