"""``cmarl-cd play``: CMARL-CD (Algorithm 1) on a common-payoff game of the user's."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    JsonOption,
    SeedOption,
    fails_cleanly,
)
from cmarlcd.cli.repeated import ALGORITHM
from cmarlcd.errors import require
from cmarlcd.limits import MAX_RUNS, check_at_most, check_seed


@app.command()
@fails_cleanly
def play(
    payoffs: Annotated[
        Path, typer.Option(help="Payoff tensor: .npy, .json (nested lists) or .csv (2 agents).")
    ],
    runs: Annotated[int, typer.Option(help="Independent learning runs.")] = 10,
    seed: SeedOption = 0,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = ALGORITHM.temperature,
    delta: Annotated[float, typer.Option(help="δ of eqs. (2)-(3).")] = ALGORITHM.delta,
    max_games: Annotated[
        int, typer.Option(help="Cap on games per run (a failure).")
    ] = ALGORITHM.max_games,
    as_json: JsonOption = False,
) -> None:
    """Learn your own common-payoff game with CMARL-CD (Algorithm 1); nothing is stored."""
    import numpy as np

    from cmarlcd.games.matrix import load_payoffs
    from cmarlcd.learners.tabular.coordination import CMARLCD as Learner
    from cmarlcd.training import fit

    config = replace(ALGORITHM, temperature=temperature, delta=delta, max_games=max_games)
    require(runs >= 1, "runs", f"must be >= 1 (got {runs})")
    check_at_most(runs, MAX_RUNS, "runs")
    check_seed(seed)
    game = load_payoffs(payoffs)
    seeds = np.random.SeedSequence(seed).spawn(runs)
    results = [fit(Learner(game.action_counts, config, seed=s), game) for s in seeds]
    doc = {
        "game": game.name,
        "action_counts": list(game.action_counts),
        "max_payoff": game.max_payoff,
        "optimal_joint_actions": [list(a) for a in game.optimal_joint_actions],
        "success_rate": sum(r.success for r in results) / runs,
        "runs": [
            {
                "greedy_joint_action": list(r.greedy_joint_action),
                "payoff": r.greedy_payoff,
                "games": r.games,
                "converged": r.converged,
                "success": r.success,
            }
            for r in results
        ],
    }
    if as_json:
        print(json.dumps(doc, indent=2))
        return
    out = Console()
    out.print(
        f"{game.name}: {game.n_agents} agents, actions {game.action_counts}, "
        f"max payoff {game.max_payoff:g} at {game.optimal_joint_actions}"
    )
    for k, r in enumerate(results):
        out.print(
            f"run {k}: greedy {r.greedy_joint_action} payoff {r.greedy_payoff:g} "
            f"after {r.games:,} games{'' if r.converged else ' (cap reached)'}"
        )
    out.print(f"success rate {100 * doc['success_rate']:.0f}% over {runs} runs (nothing stored)")
