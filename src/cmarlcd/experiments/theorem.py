"""Theorem 1 as stored runs: the numerical check of :func:`cmarlcd.theory.check_theorem1`
for a few (agents, optima) sizes, so ``reproduce`` keeps it with the other results and
``report`` renders it from the store like every table.

A run's seed is the sweep's root seed itself (the starting points are drawn from
``default_rng(root_seed)``), so a stored check equals ``cmarl-cd theory --seed N``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cmarlcd.runs import Experiment, RunSpec, Settings

EXPERIMENT = "theorem1"
#: (agents, optima) of the checks ``reproduce`` runs: the smallest case, whose phase
#: portrait is drawn, and a large one.
PAPER_SIZES = ((2, 2), (7, 5))
TEMPERATURE = 1.0


@dataclass(frozen=True)
class TheoremCheck(Settings):
    """One stored check: ``agents`` agents, ``optima`` optimal joint actions, the
    Boltzmann temperature and the number of starting points."""

    agents: int
    optima: int
    temperature: float
    starts: int


def specs(
    sizes: Sequence[tuple[int, int]] = PAPER_SIZES,
    temperature: float = TEMPERATURE,
    starts: int | None = None,
    seed: int = 0,
) -> list[RunSpec]:
    """One run per (agents, optima) size."""
    from cmarlcd.theory import DEFAULT_STARTS

    return [
        RunSpec.make(
            EXPERIMENT,
            "ode",
            TheoremCheck(n, m, temperature, DEFAULT_STARTS if starts is None else starts),
            seed,
            0,
        )
        for n, m in sizes
    ]


def run(check: TheoremCheck, seed: np.random.SeedSequence) -> dict[str, Any]:
    """The check's JSON summary; ``seed.entropy`` is the sweep's root seed."""
    from cmarlcd.theory import check_theorem1

    report = check_theorem1(
        check.agents, check.optima, check.temperature, starts=check.starts, seed=int(seed.entropy)
    )
    return report.to_dict()


def _cost(check: TheoremCheck) -> float:
    """[choice] Estimated seconds: about 1 s for 2 agents, 2.5 s for 7 (measured)."""
    return 0.5 + 0.3 * check.agents


THEOREM1 = Experiment(EXPERIMENT, TheoremCheck, run=run, cost=_cost)
