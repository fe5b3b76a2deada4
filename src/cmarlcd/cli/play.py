"""``cmarl-cd play``: CMARL-CD (Algorithm 1) on a common-payoff game of the user's, or a
policy kept with ``--save-policies`` watched in the terminal."""

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
        Path | None,
        typer.Option(
            help="Payoff tensor: .npy, .json (nested lists) or .csv (2 agents).",
            show_default=False,
        ),
    ] = None,
    policy: Annotated[
        Path | None,
        typer.Option(
            help="Instead of --payoffs: watch a policy kept with --save-policies play "
            "(.npz or .safetensors), step by step.",
            show_default=False,
        ),
    ] = None,
    episodes: Annotated[int, typer.Option(help="With --policy: episodes to watch.")] = 1,
    delay: Annotated[
        float, typer.Option(help="With --policy: seconds between two steps shown.")
    ] = 0.0,
    runs: Annotated[int, typer.Option(help="Independent learning runs.")] = 10,
    seed: SeedOption = 0,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = ALGORITHM.temperature,
    delta: Annotated[float, typer.Option(help="δ of eqs. (2)-(3).")] = ALGORITHM.delta,
    max_games: Annotated[
        int, typer.Option(help="Cap on games per run (a failure).")
    ] = ALGORITHM.max_games,
    as_json: JsonOption = False,
) -> None:
    """Learn your own common-payoff game with CMARL-CD (Algorithm 1), or watch a kept
    policy play (--policy); nothing is stored."""
    require((payoffs is None) != (policy is None), "payoffs", "give --payoffs or --policy, one")
    if policy is not None:
        watch_policy(policy, episodes, seed, delay, as_json)
        return
    assert payoffs is not None
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


def watch_policy(path: Path, episodes: int, seed: int, delay: float, as_json: bool) -> None:
    """Each step of ``episodes`` greedy episodes of the kept policy at ``path``: the
    game's picture, the agents' actions, the team's reward; each episode's return."""
    import time

    from cmarlcd.experiments.policy_watching import watch
    from cmarlcd.policies import load_policy
    from cmarlcd.policies.files import load_partner

    check_seed(seed)
    check_at_most(episodes, MAX_RUNS, "episodes")
    require(0 <= delay <= 10, "delay", f"must be in [0, 10] seconds (got {delay})")
    kept = load_policy(path)
    meta = kept.metadata
    part = meta.get("partner_part")  # a match's other team
    partner = None if part is None else load_partner(path, kept, part)
    out, doc, returns = Console(), [], {}
    for frame in watch(kept, episodes, seed, partner):
        returns[frame.episode] = returns.get(frame.episode, 0.0) + frame.reward
        if as_json:
            doc.append({"episode": frame.episode, "step": frame.step, "actions": frame.actions,
                        "reward": frame.reward, "done": frame.done})  # fmt: skip
            continue
        if frame.step == 0:
            out.print(f"{meta['algorithm']} on {meta['experiment']}, episode {frame.episode}")
        if frame.picture is not None:
            out.print(frame.picture, markup=False, highlight=False)
        if frame.step > 0:
            acts = " ".join(f"{agent}={action}" for agent, action in frame.actions.items())
            out.print(f"step {frame.step}: {acts}  reward {frame.reward:g}", highlight=False)
        if frame.done:
            out.print(f"episode {frame.episode}: return {returns[frame.episode]:g} "
                      f"in {frame.step} steps")  # fmt: skip
        if delay:
            time.sleep(delay)
    if as_json:
        print(json.dumps({"policy": str(path), "returns": list(returns.values()),
                          "steps": doc}, indent=2))  # fmt: skip
