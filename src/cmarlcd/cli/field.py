"""``cmarl-cd field``: tasks x learners x seeds at the field's protocol (EPyMARL's:
Papoudakis et al., NeurIPS 2021 Datasets and Benchmarks), beyond the paper. Each run
learns for a budget of environment steps (2.05M) with a greedy evaluation every 50,000
steps over 100 episodes; the report gives, per task and learner, the maximum and the
average return of the curve (:mod:`cmarlcd.experiments.field_metrics`). Every run is
stored as it ends, so a killed study resumes where it stopped. Besides the compiled games,
one task may be any PettingZoo environment (``--env``), played through ``train --env``'s
loop (:mod:`cmarlcd.experiments.environment`) at the same protocol."""

from __future__ import annotations

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
from cmarlcd.cli.train import ENV_ONLY, parse_env_kwargs
from cmarlcd.errors import ConfigError, require
from cmarlcd.experiments import environment as envs
from cmarlcd.experiments import games
from cmarlcd.experiments.sensor_network import SEED_BATCH
from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.deep.epymarl import epymarl_config
from cmarlcd.limits import check_seed_batch
from cmarlcd.reports.environment import environment_section
from cmarlcd.reports.game_training import game_training_section

#: The learners of the field's comparison: the independent learners, the value
#: decompositions and deep CMARL-CD.
DEFAULT_LEARNERS = "deep-iql,hysteretic-dqn,vdn,qmix,deep-cmarl-cd"
#: The field's protocol ([choice], EPyMARL's): environment steps a run, steps between
#: greedy evaluations, episodes an evaluation, seeds.
FIELD_STEPS, EVAL_INTERVAL, EVAL_EPISODES, SEEDS = 2_050_000, 50_000, 100, 5
#: [choice] Whether the field's curves start with an evaluation before learning (EPyMARL's
#: do: its first test runs at step 0, and its average return counts it).
EVAL_AT_START = True
#: The settings the deep learners of :class:`DeepConfig` (VDN, QMIX, deep IQL, hysteretic
#: DQN) play with: the registry's (the paper's DSN settings) or EPyMARL's
#: (:mod:`cmarlcd.learners.deep.epymarl`, per task: they depend on its episode length).
PRESETS = ("paper", "epymarl")


def split_tasks(text: str) -> list[str]:
    """``"foraging:5x5-2p-1f,penalty=0.1,simple_spread:N=5"`` -> the two tasks: a comma
    part with ``=`` and no ``:`` is a rule of the task before it."""
    tasks: list[str] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if "=" in part and ":" not in part:
            require(bool(tasks), "tasks", f"a rule before any task (got {text!r})")
            tasks[-1] += f",{part}"
        else:
            tasks.append(part)
    require(bool(tasks), "tasks", "needs at least one task, e.g. foraging:8x8-2p-2f-coop")
    return list(dict.fromkeys(tasks))


def evaluation_points(budget: int, interval: int) -> int:
    """The greedy evaluations of a run: one every ``interval`` steps, the last at the end."""
    require(interval >= 1, "eval_interval", f"must be >= 1 (got {interval})")
    require(
        interval <= budget,
        "eval_interval",
        f"must be at most the budget ({budget:,} steps; got {interval:,})",
    )
    return -(-budget // interval)


def with_preset(configs: tuple, preset: str, episode_steps: int) -> tuple:
    """``configs`` with the ``preset``'s settings where it has some (EPyMARL's, for the
    learners of :class:`DeepConfig` on a task of ``episode_steps``-step episodes)."""
    if preset == "paper":
        return configs
    return tuple(
        epymarl_config(c, episode_steps) if isinstance(c, DeepConfig) else c for c in configs
    )


Sweep = games.GameSweep | envs.EnvSweep


def run_field(
    sweeps: list[Sweep], run: Execution, console: Console | None, seed_batch: int
) -> dict[str, Any]:
    """Run (or resume) every task's runs as one sweep, then report each task."""
    per_task = [sweep.specs() for sweep in sweeps]
    records, done = compute_runs([s for specs in per_task for s in specs], run, "field", seed_batch)
    sections = []
    for sweep, specs in zip(sweeps, per_task, strict=True):
        keys = {spec.key for spec in specs}
        mine = [r for r in records if r.key in keys]
        if isinstance(sweep, envs.EnvSweep):
            section = environment_section(mine, run.figures)
        else:
            section = game_training_section(mine, run.figures, sweep.seed)
        sections.append(present(section, console))
    return {"tasks": sections, **run_counts(done, run.store, console)}


def env_episode_steps(env: str, kwargs: envs.EnvKwargs, given: int | None) -> int:
    """The episode length EPyMARL's preset scales by on an ``--env`` task: ``given``, or
    the one the environment declares (its ``max_cycles``), or one clear error."""
    if given is not None:
        require(given >= 1, "episode_steps", f"must be >= 1 (got {given})")
        return given
    declared = envs.declared_episode_steps(env, kwargs)
    require(
        declared is not None,
        "episode_steps",
        f"--preset epymarl scales by the episode length, and {env} declares none (no "
        "max_cycles): give it with --episode-steps N",
    )
    assert declared is not None
    return declared


def env_sweep(
    env: str, kwargs: envs.EnvKwargs, learners: tuple, copies: int, **protocol: Any
) -> envs.EnvSweep:
    """The ``--env`` task's sweep (with the random policy's runs, its floor), its errors
    named as the field's options."""
    try:
        return envs.EnvSweep(
            env=env, learners=learners, env_kwargs=kwargs, envs=copies, unit="steps", **protocol
        )
    except ConfigError as error:
        names = {"algorithms": "learners", "runs": "seeds", "curve_points": "eval_interval"}
        parameter = names.get(error.parameter, error.parameter)
        raise ConfigError(parameter, f"{env}: {error.message}") from None


@app.command(short_help="Beyond the paper: the field's protocol on its cooperative benchmarks.")
@fails_cleanly
@with_deep_execution
def field(
    tasks: Annotated[
        str | None,
        typer.Option(
            help="Comma list of compiled tasks, each foraging:TASK[,rule=value...] or "
            "simple_spread[:N=3,...], e.g. foraging:8x8-2p-2f-coop,simple_spread.",
            show_default=False,
        ),
    ] = None,
    env: Annotated[
        str | None,
        typer.Option(
            help="One more task (or the only one): MODULE:FACTORY returning a PettingZoo "
            "ParallelEnv with discrete actions, played through train --env's loop, with a "
            "uniform random policy's runs as its floor.",
            show_default=False,
        ),
    ] = None,
    env_kwargs: Annotated[
        str, typer.Option(help="With --env: the factory's keyword arguments, a JSON object.")
    ] = "{}",
    envs_per_run: Annotated[
        int,
        typer.Option(
            "--envs", help="With --env: copies of the environment each run plays at once."
        ),
    ] = envs.DEFAULT_ENVS,
    episode_steps: Annotated[
        int | None,
        typer.Option(
            help="With --env and --preset epymarl: the episode length EPyMARL's settings "
            "scale by [default: the environment's max_cycles].",
            show_default=False,
        ),
    ] = None,
    learners: Annotated[
        str, typer.Option(help=f"Comma list of {registry.learner_names()}.")
    ] = DEFAULT_LEARNERS,
    seeds: Annotated[int, typer.Option(help="Runs (seeds) per task and learner.")] = SEEDS,
    steps: Annotated[
        str, typer.Option(help="Environment steps of each run (2.05M allowed).")
    ] = "2.05M",
    eval_interval: Annotated[
        str, typer.Option(help="Environment steps between greedy evaluations.")
    ] = "50k",
    eval_episodes: Annotated[str, typer.Option(help="Episodes of each greedy evaluation.")] = str(
        EVAL_EPISODES
    ),
    inputs: Annotated[
        str,
        typer.Option(
            help="What the deep learners read: observations (every agent's, joined) or "
            "own-observations (each agent its own; VDN, QMIX, deep IQL, hysteretic DQN)."
        ),
    ] = "observations",
    time_left: Annotated[
        bool,
        typer.Option(
            help="With --tasks: each agent also reads the time left in the episode, "
            "(T - t) / T, after its observation (a time-aware input; the runs of each "
            "setting are stored apart)."
        ),
    ] = False,
    seed_batch: Annotated[
        int, typer.Option(help="Seeds of a deep learner trained together in one model.")
    ] = SEED_BATCH,
    preset: Annotated[
        str,
        typer.Option(
            help="Settings of VDN, QMIX, deep IQL and hysteretic DQN: paper (the registry's, "
            "the paper's DSN settings) or epymarl (EPyMARL's, per task; --set applies "
            "after it). Deep CMARL-CD keeps its own."
        ),
    ] = "paper",
    eval_at_start: Annotated[
        bool,
        typer.Option(
            help="Evaluate the greedy policy before learning too (a curve point at step 0, "
            "in the average return), as EPyMARL does."
        ),
    ] = EVAL_AT_START,
    seed: SeedOption = 0,
    settings: SetOption = "",
    *,
    run: Execution,
) -> None:
    """Tasks x learners x seeds at the field's protocol: each run learns for a budget of
    environment steps with a greedy evaluation at every interval; per task and learner,
    the curve, the maximum return (with its 95 % interval over the seeds) and the average
    return; stored and resumable."""
    require(
        tasks is not None or env is not None,
        "tasks",
        "give --tasks (e.g. foraging:8x8-2p-2f-coop), --env MODULE:FACTORY, or both",
    )
    if env is None:
        given = {"env_kwargs": env_kwargs, "envs": envs_per_run, "episode_steps": episode_steps}
        defaults = {**ENV_ONLY, "episode_steps": None}
        for name, value in given.items():
            require(value == defaults[name], name, "applies to --env only")
    names = parse_names(learners, "learners")
    configs = tuple(registry.require_learner(name, "learners") for name in names)
    require(preset in PRESETS, "preset", f"must be one of {', '.join(PRESETS)} (got {preset!r})")
    require_torch_for(names, "learners")
    check_seed_batch(seed_batch)
    require(seeds >= 1, "seeds", f"must be >= 1 (got {seeds})")
    budget = parse_count(steps, "steps")
    points = evaluation_points(budget, parse_count(eval_interval, "eval_interval"))
    evaluated = parse_count(eval_episodes, "eval_episodes")
    require(
        inputs in games.GAME_INPUTS,
        "inputs",
        f"must be one of {', '.join(games.GAME_INPUTS)} (got {inputs!r})",
    )
    apply_settings(settings, configs)  # bad settings refused before any task is made
    sweeps = []
    for task in split_tasks(tasks) if tasks is not None else []:
        try:
            family, rules = games.parse_game(task)
            chosen = apply_settings(settings, with_preset(configs, preset, rules.spec().max_steps))
            sweeps.append(
                games.GameSweep(
                    game=family.game,
                    learners=chosen,
                    episodes=(budget,),
                    unit="steps",
                    runs=seeds,
                    eval_episodes=evaluated,
                    seed=seed,
                    curve_points=points,
                    curve_eval_episodes=evaluated,
                    options=family.options(rules, inputs, time_left),
                    eval_at_start=eval_at_start,
                )
            )
        except ConfigError as error:
            parameter = {"algorithms": "learners", "game": "tasks"}.get(error.parameter)
            raise ConfigError(parameter or error.parameter, f"{task}: {error.message}") from None
    if env is not None:
        require(not time_left, "time_left", "applies to --tasks only (a compiled game's clock)")
        kwargs = parse_env_kwargs(env_kwargs)
        episode = env_episode_steps(env, kwargs, episode_steps) if preset == "epymarl" else 1
        chosen = apply_settings(settings, with_preset(configs, preset, episode))
        protocol = {
            "episodes": budget, "runs": seeds, "eval_episodes": evaluated, "seed": seed,
            "curve_points": points, "inputs": inputs, "eval_at_start": eval_at_start,
        }  # fmt: skip
        sweeps.append(env_sweep(env, kwargs, chosen, envs_per_run, **protocol))
    print_results(run, lambda console: run_field(sweeps, run, console, seed_batch))
