"""The coordination-degree rules shared by Algorithms 1 and 2 (and deep CMARL-CD):
reinforcing the selected action (eqs. 2-3, 14-15), clipping the degrees (Section IV-D),
the stopping rule, and the validation of the degree settings. Compiled, over plain
arrays; each agent's row is padded to the largest action count and ``count`` says how
many entries are real."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from cmarlcd.errors import require


@njit(cache=True)
def reinforce(c_row: np.ndarray, count: int, action: int, step: float) -> None:
    """Eqs. (2)-(3) and (14)-(15): the selected action ``+step``, every other ``-step``."""
    for a in range(count):
        if a == action:
            c_row[a] += step
        else:
            c_row[a] -= step


@njit(cache=True)
def clip_degrees(c_row: np.ndarray, count: int, c_min: float, c_max: float) -> None:
    """Section IV-D: confine every coordination degree to ``[c_min, c_max]``."""
    for a in range(count):
        c_row[a] = min(max(c_row[a], c_min), c_max)


@njit(cache=True)
def degree_step(c_row: np.ndarray, count: int, action: int, new_record: bool, params) -> None:
    """Algorithm 2, lines 16-18, for one agent at one visit that reached its state's
    record: on a new record the degrees are first reset to ``c_init`` and the step is
    ``delta_reset``, on a tie it is ``delta``; the selected action ``+step``, every other
    ``-step`` (eqs. 14-15), then clipped to ``[c_min, c_max]`` (Section IV-D).
    ``params`` has ``delta``, ``delta_reset``, ``c_init``, ``c_min`` and ``c_max``."""
    step = params.delta
    if new_record:
        for a in range(count):
            c_row[a] = params.c_init
        step = params.delta_reset
    reinforce(c_row, count, action, step)
    clip_degrees(c_row, count, params.c_min, params.c_max)


@njit(cache=True)
def is_pure(p: np.ndarray, counts: np.ndarray, threshold: float) -> bool:
    """The stopping rule: every agent has some action with probability above ``threshold``."""
    for i in range(counts.shape[0]):
        pure = False
        for a in range(counts[i]):
            if p[i, a] > threshold:
                pure = True
                break
        if not pure:
            return False
    return True


def check_degree_settings(config: Any) -> None:
    """Validate Algorithm 2's steps, temperature and degree bounds (``delta``,
    ``delta_reset``, ``temperature`` > 0; ``0 < c_min <= c_init <= c_max``) of any
    config that has them (the tabular and the deep learner)."""
    for name in ("delta", "delta_reset", "temperature"):
        value = getattr(config, name)
        require(bool(np.isfinite(value)) and value > 0, name, f"must be > 0 (got {value})")
    lo, hi, init = config.c_min, config.c_max, config.c_init
    require(bool(np.isfinite(lo)) and lo > 0, "c_min", f"must be > 0 (got {lo})")
    require(bool(np.isfinite(hi)) and lo <= hi, "c_max", f"must be >= c_min = {lo} (got {hi})")
    require(lo <= init <= hi, "c_init", f"must lie in [c_min, c_max] = [{lo}, {hi}] (got {init})")
