"""``cmarl-cd train``: any learner on any PettingZoo ``ParallelEnv`` with discrete actions
(``--env``, :mod:`cmarlcd.experiments.environment`), or on a game of the compiled protocol
(``--game``, :mod:`cmarlcd.experiments.games`), beyond the paper."""

from __future__ import annotations

import json
from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import registry
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    SeedOption,
    SetOption,
    apply_settings,
    fails_cleanly,
    parse_count,
    parse_names,
)
from cmarlcd.cli.sweeps import (
    Execution,
    compute_runs,
    present,
    print_results,
    require_torch_for,
    run_counts,
    with_deep_execution,
)
from cmarlcd.errors import ConfigError, require
from cmarlcd.experiments import environment as envs
from cmarlcd.experiments import games
from cmarlcd.experiments.sensor_network import SEED_BATCH
from cmarlcd.limits import check_seed_batch
from cmarlcd.reports.environment import environment_section
from cmarlcd.reports.game_training import game_training_section

DEFAULT_ALGORITHMS = "vdn,qmix,deep-cmarl-cd"


def parse_env_kwargs(text: str) -> envs.EnvKwargs:
    """``'{"N": 3}'`` -> (("N", 3),): a JSON object of keyword arguments."""
    try:
        given = json.loads(text)
    except json.JSONDecodeError as error:
        raise ConfigError("env_kwargs", f"not JSON ({error.msg}): {text!r}") from None
    require(isinstance(given, dict), "env_kwargs", f"expected a JSON object (got {text!r})")
    return tuple(sorted(given.items()))


def run_training(sweep: envs.EnvSweep, run: Execution, console: Console | None) -> dict[str, Any]:
    """Run (or resume) the study and report it; return its JSON document."""
    records, done = compute_runs(sweep.specs(), run, "train")
    doc = present(environment_section(records, run.figures), console)
    return {**doc, **run_counts(done, run.store, console)}


def run_game_training(
    sweep: games.GameSweep, run: Execution, console: Console | None, seed_batch: int
) -> dict[str, Any]:
    """Run (or resume) a study on a compiled game and report it; its JSON document."""
    records, done = compute_runs(sweep.specs(), run, "train", seed_batch)
    doc = present(game_training_section(records, run.figures, sweep.seed), console)
    return {**doc, **run_counts(done, run.store, console)}


#: The options that only ``--env`` reads, with their defaults.
ENV_ONLY = {"env_kwargs": "{}", "reward": "sum", "envs": envs.DEFAULT_ENVS}
#: ``--inputs`` with ``--game``: a compiled game's features are every agent's observation
#: joined, its "state" (:data:`cmarlcd.experiments.games.GAME_INPUTS`).
GAME_INPUTS = {"state": "observations"}


@app.command(short_help="Beyond the paper: learners on any PettingZoo ParallelEnv.")
@fails_cleanly
@with_deep_execution
def train(
    env: Annotated[
        str | None,
        typer.Option(
            help="The environment, MODULE:FACTORY returning a PettingZoo ParallelEnv with "
            "discrete actions, e.g. mpe2.simple_spread_v3:parallel_env."
        ),
    ] = None,
    game: Annotated[
        str | None,
        typer.Option(
            help="Instead of --env, a compiled game: foraging:TASK[,rule=value...] (Level-"
            "Based Foraging, e.g. foraging:8x8-2p-2f-coop or foraging:2s-10x10-3p-3f) or "
            "simple_spread[:N=3,local_ratio=0.5,max_cycles=25] (MPE), played with no Python "
            "per step, deep learners seed-batched."
        ),
    ] = None,
    env_kwargs: Annotated[
        str,
        typer.Option(help="Keyword arguments of the factory, a JSON object, e.g. '{\"N\": 3}'."),
    ] = "{}",
    algorithms: Annotated[
        str, typer.Option(help=f"Comma list of {registry.learner_names()}.")
    ] = DEFAULT_ALGORITHMS,
    episodes: Annotated[
        str, typer.Option(help="Learning episodes of each run (10k allowed).")
    ] = "2000",
    steps: Annotated[
        str | None,
        typer.Option(
            help="Instead of --episodes: the learning budget in environment steps (2.05M "
            "allowed), to the end of the episodes in play when it is reached; the curve's "
            "points and ε's annealing count steps too."
        ),
    ] = None,
    runs: Annotated[int, typer.Option(help="Runs per learner.")] = 3,
    eval_episodes: Annotated[
        str, typer.Option(help="Greedy evaluation episodes at each point of the curve.")
    ] = "20",
    curve_points: Annotated[
        int, typer.Option(help="Evenly spaced points of the learning curve.")
    ] = envs.CURVE_POINTS,
    reward: Annotated[
        str, typer.Option(help="The team's reward from the agents': sum or mean.")
    ] = "sum",
    inputs: Annotated[
        str,
        typer.Option(
            help="What the learners read: state (the env's state()), observations (joined), or "
            "own-observations (VDN, QMIX, deep IQL, hysteretic DQN: each agent its own, the "
            "mixer the state). With --game, state and observations are every agent's "
            "observation joined."
        ),
    ] = "state",
    envs_per_run: Annotated[
        int,
        typer.Option(
            "--envs",
            help="Copies of the environment each run plays at once (a deep learner acts "
            "for all with one forward pass; 1: one at a time, as before 0.6.0).",
        ),
    ] = envs.DEFAULT_ENVS,
    seed_batch: Annotated[
        int,
        typer.Option(help="With --game: seeds of a deep learner trained together in one model."),
    ] = SEED_BATCH,
    seed: SeedOption = 0,
    settings: SetOption = "",
    *,
    run: Execution,
) -> None:
    """Learn on any PettingZoo ParallelEnv with discrete actions, or on a compiled game:
    each learner's learning curve (greedy return, mean over runs) beside a uniform random
    policy's, stored and resumable; a table and a figure."""
    require(
        (env is None) != (game is None),
        "env",
        "give one of --env MODULE:FACTORY and --game NAME:TASK (e.g. --game "
        "foraging:8x8-2p-2f-coop)",
    )
    names = parse_names(algorithms, "algorithms")
    configs = tuple(registry.require_learner(name) for name in names)
    require_torch_for(names)
    if game is not None:
        given = {"env_kwargs": env_kwargs, "reward": reward, "envs": envs_per_run}
        for name, value in given.items():
            require(value == ENV_ONLY[name], name, "applies to --env only, not to --game")
        check_seed_batch(seed_batch)
        evaluated = parse_count(eval_episodes, "eval_episodes")
        budget = parse_count(episodes, "episodes") if steps is None else parse_count(steps, "steps")
        family, rules = games.parse_game(game)
        game_sweep = games.GameSweep(
            game=family.game,
            learners=apply_settings(settings, configs),
            episodes=(budget,),
            unit="episodes" if steps is None else "steps",
            runs=runs,
            eval_episodes=evaluated,
            seed=seed,
            curve_points=curve_points,
            curve_eval_episodes=evaluated,
            options=family.options(rules, GAME_INPUTS.get(inputs, inputs)),
        )
        print_results(run, lambda console: run_game_training(game_sweep, run, console, seed_batch))
        return
    assert env is not None
    learners = apply_settings(settings, configs)
    for config in learners:
        if compiled := getattr(config, "compiled_only", tuple)():
            raise ConfigError(
                "set",
                f"{config.name}.{compiled[0]} is run by the compiled loop only (--game NAME:TASK); "
                "--env plays any ParallelEnv, where the learner would run without it",
            )
    sweep = envs.EnvSweep(
        env=env,
        learners=learners,
        episodes=parse_count(episodes, "episodes")
        if steps is None
        else parse_count(steps, "steps"),
        unit="episodes" if steps is None else "steps",
        runs=runs,
        eval_episodes=parse_count(eval_episodes, "eval_episodes"),
        env_kwargs=parse_env_kwargs(env_kwargs),
        curve_points=curve_points,
        reward=reward,
        inputs=inputs,
        seed=seed,
        envs=envs_per_run,
    )
    print_results(run, lambda console: run_training(sweep, run, console))
