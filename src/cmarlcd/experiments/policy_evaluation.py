"""A kept policy played greedily again (``cmarl-cd evaluate``): on the environment or
compiled game of the run that kept it, by default with that run's own last evaluation
(the same episodes and seeds, so the same return as the store's last curve point), or for
``episodes`` episodes from ``seed``, or (a ``train --env`` policy) on another environment
of the same shapes."""

from __future__ import annotations

from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.experiments import environment as envs
from cmarlcd.runs import RunSpec


def run_spec(meta: dict[str, Any]) -> RunSpec:
    """The run a policy file names (its identity and seeds)."""
    return RunSpec(meta["experiment"], meta["algorithm"], meta["config_json"],
                   int(meta["root_seed"]), int(meta["run_index"]), meta["stream_json"])  # fmt: skip


def evaluate_policy(
    policy: Any,
    episodes: int | None = None,
    seed: int | None = None,
    env: str | None = None,
    env_kwargs: envs.EnvKwargs | None = None,
    partner: Any = None,
) -> dict[str, Any]:
    """Play ``policy`` greedily; its mean return (the team's, as the run counted it), or
    for a tournament match's policy (with the other team's, ``partner``) the wins."""
    meta = policy.metadata
    spec = run_spec(meta)
    if meta.get("experiment") != envs.EXPERIMENT:
        require(env is None and env_kwargs is None, "env", "applies to train --env's policies")
        if spec.experiment == MATCHES:
            from cmarlcd.experiments.match_policies import evaluate_match

            return evaluate_match(policy, partner, spec, episodes, seed)
        if spec.experiment in REPEATED_GAMES:
            return evaluate_on_repeated_game(policy, spec)
        return evaluate_on_game(policy, spec, episodes, seed)
    settings = envs.EnvRun.from_config(spec.config)
    where, kwargs = env or settings.env, settings.env_kwargs if env_kwargs is None else env_kwargs
    own = episodes is None and seed is None and env is None and env_kwargs is None
    count = settings.eval_episodes if episodes is None else episodes
    require(count >= 1, "episodes", f"must be >= 1 (got {count})")
    copies = min(settings.envs, count)
    if own:  # the run's last evaluation: its point's seed sequence
        point = envs.point_seed(spec.seed_sequence().spawn(3)[2], settings.episodes)
    else:
        point = np.random.SeedSequence(0 if seed is None else seed)
    played = envs.make_copies(where, kwargs, settings.inputs, copies)
    _, counts = envs.check_copies(played, settings.inputs, envs.copy_seeds(point, copies))
    require(
        list(counts) == list(policy.counts),
        "env",
        f"{where}: its agents have {list(counts)} actions; the policy's {list(policy.counts)}",
    )
    from cmarlcd.training.episodes import play_copies

    stats = play_copies(
        played, policy, count, learn=False, seeds=envs.copy_seeds(point, copies),
        global_reward=envs.REWARDS[settings.reward],
    )  # fmt: skip
    return {
        "env": where, "env_kwargs": dict(kwargs), "algorithm": meta["algorithm"],
        "episodes": count, "mean_return": float(stats.returns.mean()),
        "std_return": float(stats.returns.std()), "mean_steps": float(stats.lengths.mean()),
        "seeds": _seeds_said(own, seed),
    }  # fmt: skip


def _seeds_said(own: bool, seed: int | None) -> str:
    return "the run's last evaluation" if own else f"seed {0 if seed is None else seed}"


def episodic_game(name: str) -> Any:
    """The compiled game of an episodic experiment, by its store name."""
    from cmarlcd.experiments.games import FAMILIES
    from cmarlcd.experiments.scaling import SCALING_GAME
    from cmarlcd.experiments.sensor_network import DSN_GAME

    games = {
        g.experiment: g for g in (DSN_GAME, SCALING_GAME, *(f.game for f in FAMILIES.values()))
    }
    require(name in games, "policy", f"a policy of {name}'s runs, which evaluate does not play")
    return games[name]


def evaluate_on_game(
    policy: Any, spec: RunSpec, episodes: int | None, seed: int | None
) -> dict[str, Any]:
    """A table kept by a run of a compiled game, played as its last curve point was (the
    curve's episodes and stream at the last budget), or ``episodes`` from ``seed``."""
    from cmarlcd.experiments.episodic import EpisodicRun, is_deep, keyed_rng
    from cmarlcd.training.greedy import GreedyPolicy

    game = episodic_game(spec.experiment)
    settings = EpisodicRun.from_config(spec.config)
    played = game.with_options(settings.options)
    own = episodes is None and seed is None
    count = settings.curve_eval_episodes if episodes is None else episodes
    require(count >= 1, "episodes", f"must be >= 1 (got {count})")
    if own:  # the run's last curve point: its evaluation stream at the last budget
        eval_seed = own_eval_seed(spec, is_deep(settings.learner))
        rng = keyed_rng(eval_seed, 1, settings.schedule()[-1])
    else:
        rng = np.random.default_rng(0 if seed is None else seed)
    n_agents = len(played.spec.action_counts)
    check_actions(policy, played.spec.action_counts)
    if policy.kind == "table":
        table = policy.actions
        require(
            table.shape == (played.spec.n_states, n_agents),
            "policy",
            f"its table is {table.shape}; the game's states x agents {played.spec.n_states} "
            f"x {n_agents}",
        )
        stats = GreedyPolicy(played.spec, table=table).evaluate(count, rng)
    else:
        stats = play_network(played.spec, policy, count, rng)
    return {
        "game": spec.experiment, "algorithm": spec.algorithm, "episodes": count,
        "mean_return": float(stats.returns.sum()) / count,
        "std_return": float(stats.returns.std()), "mean_steps": float(stats.lengths.mean()),
        "success_rate": int(game.success(stats).sum()) / count,
        "seeds": _seeds_said(own, seed),
    }  # fmt: skip


#: The experiment whose runs are matches, each keeping one policy a team.
MATCHES = "tournament"
#: The experiments whose runs play one repeated game, each kept policy a greedy joint action.
REPEATED_GAMES = ("compare", "repeated")


def repeated_game(spec: RunSpec) -> Any:
    """The repeated game a stored run of ``compare`` or ``repeated`` played."""
    from cmarlcd.experiments import compare, repeated

    return {"compare": compare, "repeated": repeated}[spec.experiment].game_of_run(spec)


def evaluate_on_repeated_game(policy: Any, spec: RunSpec) -> dict[str, Any]:
    """A greedy joint action kept by a run of ``compare`` or ``repeated``: its expected
    payoff on the game the run played (a random game remade from the run's seeds), as
    the run stored it."""
    game = repeated_game(spec)
    check_actions(policy, game.action_counts)
    joint = tuple(int(a) for a in policy.greedy(0))
    return {
        "game": spec.config.get("game", spec.experiment), "algorithm": spec.algorithm,
        "episodes": 1,
        "greedy_joint_action": list(joint), "mean_return": float(game.payoff(joint)),
        "std_return": 0.0, "mean_steps": 1.0, "optimal": bool(game.is_optimal(joint)),
        "seeds": "the run's game (the expected payoff of its greedy joint action)",
    }  # fmt: skip


def check_actions(policy: Any, counts: Any) -> None:
    """A kept policy plays a game whose agents have the actions it learned with."""
    theirs, ours = [int(c) for c in policy.counts], [int(c) for c in counts]
    require(theirs == ours, "policy", f"its agents have {theirs} actions; the game's {ours}")


def own_eval_seed(spec: RunSpec, deep: bool) -> np.random.SeedSequence:
    """The evaluation seed of a compiled game's run: a deep run's streams are (training,
    evaluation), a table learner's (environment, agent, evaluation)."""
    return spec.seed_sequence().spawn(2)[1] if deep else spec.seed_sequence().spawn(3)[2]


def play_network(spec: Any, policy: Any, episodes: int, rng: np.random.Generator) -> Any:
    """``episodes`` greedy episodes of a network policy on a compiled game, drawn from
    ``rng`` as the compiled loop's evaluation draws them
    (:func:`cmarlcd.training.loop.play_greedy`: the game's kernels called in the same
    order, so the same episodes as the run's own evaluation)."""
    from cmarlcd.training.tabular import EpisodeStats

    game, env = spec.kernels, spec.new_env()
    legal = np.zeros((spec.n_agents, spec.width), np.bool_)
    x = np.zeros(spec.n_features, np.float32)
    rewards = np.zeros(spec.n_teams)
    returns, lengths = np.zeros(episodes), np.zeros(episodes, np.int64)
    terminated = np.zeros(episodes, np.bool_)
    reads_state = bool(policy.metadata.get("n_states"))
    for e in range(episodes):
        game.reset(env, rng)
        turns, total = 0, 0.0
        while turns < spec.max_steps:
            if reads_state:
                state: Any = game.state(env, 0)
            else:
                game.features(env, 0, x)
                state = x
            game.legal(env, legal)
            masks = [row[:count] for row, count in zip(legal, spec.action_counts, strict=True)]
            joint = policy.greedy_many([state], [masks])[0].astype(np.int64)
            game.step(env, joint, rng, rewards)
            total += rewards[0]
            turns += 1
            if game.done(env):
                break
        returns[e], lengths[e], terminated[e] = total, turns, game.done(env)
    return EpisodeStats(returns, lengths, terminated)


def stored_return(record: Any) -> float:
    """The mean return at a stored run's last curve point (``train --env``'s curve rows
    are [budget, return, steps]; a compiled game's [budget, success, return, steps])."""
    if record.key.experiment in REPEATED_GAMES:
        return float(record.metrics["greedy_payoff"])
    column = 1 if record.key.experiment == envs.EXPERIMENT else 2
    return float(record.metrics["curve"][-1][column])
