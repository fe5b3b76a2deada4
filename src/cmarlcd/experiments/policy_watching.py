"""A kept policy watched (``cmarl-cd play --policy``): played greedily, one episode after
another, in the PettingZoo environment of the run that kept it (a compiled game's
``ParallelEnv``: :class:`~cmarlcd.games.foraging.env.ForagingEnv`,
:class:`~cmarlcd.games.spread.env.SimpleSpreadEnv`,
:class:`~cmarlcd.games.sensor_network.env.SensorNetworkEnv`, else
:class:`~cmarlcd.games.env.KernelParallelEnv`; ``train --env``'s factory), with the
policy's own :meth:`act`, each step a frame: the environment's text picture where it
draws one (``render_mode="ansi"``), each agent's action and reward."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.experiments import environment as envs
from cmarlcd.experiments.policy_evaluation import (
    MATCHES,
    REPEATED_GAMES,
    episodic_game,
    repeated_game,
    run_spec,
)
from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.time_left import time_left_features


@dataclass
class Frame:
    """One step of a watched episode (step 0: the state it started in, no actions):
    ``reward`` is the team's, as the run counted it (the game's team reward; for
    ``train --env``, its agents' rewards summed or averaged as the run said)."""

    episode: int
    step: int
    picture: str | None
    actions: dict[str, int] = field(default_factory=dict)
    rewards: dict[str, float] = field(default_factory=dict)
    reward: float = 0.0
    done: bool = False


def policy_env(policy: Any) -> Any:
    """The ``ParallelEnv`` the policy's run played, drawing text where it can."""
    meta = policy.metadata
    spec = run_spec(meta)
    if spec.experiment == envs.EXPERIMENT:
        settings = envs.EnvRun.from_config(spec.config)
        try:  # its text picture, where the factory draws one
            return envs.make_env(settings.env, {**dict(settings.env_kwargs), "render_mode": "ansi"})
        except Exception:
            return envs.make_env(settings.env, settings.env_kwargs)
    if spec.experiment == MATCHES:  # the battlefield of the match's readings
        from cmarlcd.experiments.tournament import Pairing
        from cmarlcd.games.battlefield.env import BattlefieldEnv

        return BattlefieldEnv(Pairing.from_config(spec.config).rules, render_mode="ansi")
    if spec.experiment in REPEATED_GAMES:  # the repeated game the run played
        from cmarlcd.games.matrix.env import MatrixGameEnv

        return MatrixGameEnv(repeated_game(spec), render_mode="ansi")
    from cmarlcd.experiments.episodic import EpisodicRun
    from cmarlcd.experiments.games import FAMILIES
    from cmarlcd.games.foraging.env import ForagingEnv
    from cmarlcd.games.sensor_network.env import SensorNetworkEnv
    from cmarlcd.games.spread.env import SimpleSpreadEnv

    options = EpisodicRun.from_config(spec.config).options
    family = FAMILIES.get(spec.experiment)
    if family is not None:  # the task's own environment (its observations: the features)
        env_of = {"foraging": ForagingEnv, "simple_spread": SimpleSpreadEnv}[family.name]
        return env_of(family.rules_of(options), render_mode="ansi")
    game = episodic_game(spec.experiment).with_options(options)
    if game.spec.name == SensorNetworkEnv.metadata["name"] and not options:
        return SensorNetworkEnv(render_mode="ansi")
    return KernelParallelEnv(game.spec, render_mode="ansi")


def watch(policy: Any, episodes: int = 1, seed: int = 0, partner: Any = None) -> Iterator[Frame]:
    """``episodes`` greedy episodes of ``policy``, the first reset with ``seed`` (the
    next ones continue its stream), frame by frame; a match's policy plays against the
    other team's kept policy ``partner`` (the reward: the policy's team's)."""
    require(episodes >= 1, "episodes", f"must be >= 1 (got {episodes})")
    env = policy_env(policy)
    team_reward = _team_reward(policy, env)
    if run_spec(policy.metadata).experiment == MATCHES:
        require(partner is not None, "policy", "a match's policy plays with its partner's file")
        policy = _MatchPlayers(policy, partner, env, seed)
    reads_state = policy.metadata.get("inputs", "state") == "state"
    features = (
        np.zeros(env.spec.n_features, np.float32)
        if isinstance(env, KernelParallelEnv) and policy.kind == "network"
        and not policy.metadata.get("n_states")
        else None
    )  # fmt: skip
    clocked = features is not None and _reads_time_left(policy)
    for episode in range(episodes):
        observations, infos = env.reset(seed=seed if episode == 0 else None)
        yield Frame(episode, 0, _picture(env))
        step = 0
        while env.agents:
            masks = {a: infos.get(a, {}).get("action_mask") for a in env.agents}
            given = None if any(m is None for m in masks.values()) else masks
            if features is not None:  # a compiled game's features, as the run read them
                env.spec.kernels.features(env.env, 0, features)
                x = features  # and each agent's time left, where the run read it
                if clocked:
                    x = time_left_features(features, env.spec.n_agents, step, env.spec.max_steps)
                legal = None if given is None else [given[a] for a in env.agents]
                actions = dict(zip(env.agents, policy.greedy(x, legal), strict=True))
            else:
                state = env.state() if reads_state else None
                actions = policy.act(observations, state=state, masks=given)
            observations, rewards, terms, truncs, infos = env.step(actions)
            step += 1
            done = not env.agents or all(terms.get(a) or truncs.get(a) for a in actions)
            said = {a: float(r) for a, r in rewards.items()}
            yield Frame(episode, step, _picture(env), {a: int(x) for a, x in actions.items()},
                        said, team_reward(said), done)  # fmt: skip
            if done:
                break


def _reads_time_left(policy: Any) -> bool:
    """Whether the run that kept ``policy`` played a compiled game with the time left
    after each agent's observation (``field --time-left``)."""
    from cmarlcd.experiments.episodic import EpisodicRun
    from cmarlcd.experiments.games import FAMILIES, reads_time_left

    spec = run_spec(policy.metadata)
    return spec.experiment in FAMILIES and reads_time_left(
        EpisodicRun.from_config(spec.config).options
    )


class _MatchPlayers:
    """Both teams of a match, acting as one policy in :func:`watch`'s loop: each team's
    kept policy as its side played at evaluation (a tabular side's unseen states by its
    reading, its draws from a stream of ``seed``)."""

    kind = "match"

    def __init__(self, policy: Any, partner: Any, env: Any, seed: int) -> None:
        from cmarlcd.experiments.match_policies import by_team

        self.teams = by_team(policy, partner)
        self.metadata = {"inputs": "observations"}
        self.env, self.rngs = env, np.random.default_rng([seed, 1]).spawn(2)
        spec = env.spec
        self.legal = np.zeros((spec.n_agents, spec.width), np.bool_)
        self.x = np.zeros(spec.n_features, np.float32)
        self.joint = np.zeros(spec.n_agents, np.int64)

    def act(self, observations: Any, state: Any = None, masks: Any = None) -> dict[str, int]:
        from cmarlcd.experiments.match_policies import joint_action

        env = self.env
        joint_action(self.teams, env.spec, env.env, self.legal, self.x, self.rngs, self.joint)
        return {a: int(x) for a, x in zip(env.agents, self.joint, strict=True)}


def _picture(env: Any) -> str | None:
    if getattr(env, "render_mode", None) != "ansi":
        return None
    text = env.render()
    return text if isinstance(text, str) else None


def _team_reward(policy: Any, env: Any) -> Any:
    """How the run counted a step's team reward from the agents' rewards."""
    spec = run_spec(policy.metadata)
    if spec.experiment == envs.EXPERIMENT:
        return envs.REWARDS[envs.EnvRun.from_config(spec.config).reward]
    team = int(policy.metadata.get("team", 0))  # a match's: its own team's
    return lambda rewards: float(env.team_rewards[team])  # the game's, for its team
