"""Compiled episodes of any tabular learner on any game: learning, and greedy evaluation.

:func:`train_episodes` and :func:`evaluate_episodes` are templates (see
:mod:`cmarlcd.compiled`): ``game`` is bound to a game's kernels
(:mod:`cmarlcd.games.spec`) and ``learner`` to a tabular learner's
(:mod:`cmarlcd.learners.tabular`), and numba compiles one loop per pair. With the same
seeds they consume the random streams exactly as the generic ``ParallelEnv`` loop of
:mod:`cmarlcd.training.episodes` does (the environment's generator for starts and
transitions, the learner's for actions), so both learn the same tables.

A state's legal-action masks are read from the game on its first visit and handed to the
learner's ``init_state``; a game's masks must therefore depend on the state index alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cmarlcd.compiled import Unbound, specialise
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.tabular import TabularConfig, greedy_policy, init_tables

game = Unbound("game")
learner = Unbound("learner")


def train_episodes(
    env, tables, params, counts, seen, episodes, max_steps, env_rng, agent_rng
) -> int:
    """Template: ``episodes`` learning episodes; returns the environment steps taken.

    Per step: the learner acts in ``s`` (initialised on its first visit), the game steps,
    and the learner observes the transition; after each episode, ``end_episode``.
    ``seen[s]`` marks the states initialised so far (kept across calls).
    """
    n_agents = counts.shape[0]
    states = np.zeros(max_steps, dtype=np.int64)
    joints = np.zeros((max_steps, n_agents), dtype=np.int64)
    rewards = np.zeros(max_steps)
    team_rewards = np.zeros(1)
    legal = np.zeros((n_agents, counts.max()), dtype=np.bool_)
    total = 0
    for _ in range(episodes):
        game.reset(env, env_rng)
        s = game.state(env, 0)
        terminal = False
        length = 0
        while True:
            if not terminal and not seen[s]:
                game.legal(env, legal)
                learner.init_state(tables, params, s, legal, counts)
                seen[s] = True
            if length > 0:
                learner.observe(tables, params, states, joints, rewards, length - 1, s, terminal)
            if terminal or length == max_steps:
                break
            learner.act(tables, params, s, counts, agent_rng, joints[length])
            game.step(env, joints[length], env_rng, team_rewards)
            states[length] = s
            rewards[length] = team_rewards[0]
            length += 1
            terminal = game.done(env)
            s = game.state(env, 0)
        learner.end_episode(tables, params, states, joints, rewards, length, counts)
        total += length
    return total


def evaluate_episodes(env, policy, counts, episodes, max_steps, env_rng, returns, lengths) -> None:
    """Template: ``episodes`` episodes with the fixed joint policy ``policy[state]``,
    writing each episode's undiscounted return and length. ``learner`` is unused.

    [choice] An action the game forbids in a state (one the learner never visited, whose
    row was set up as if every action were legal) is replaced by the agent's lowest
    legal action there: the greedy choice among equal untouched values. Masks depend on
    the state alone, so each state's row is checked once, on its first visit.
    """
    n_agents = counts.shape[0]
    playing = policy.copy()
    checked = np.zeros(policy.shape[0], dtype=np.bool_)
    team_rewards = np.zeros(1)
    legal = np.zeros((n_agents, counts.max()), dtype=np.bool_)
    for e in range(episodes):
        game.reset(env, env_rng)
        total, steps = 0.0, 0
        while steps < max_steps:
            s = game.state(env, 0)
            if not checked[s]:
                game.legal(env, legal)
                for i in range(n_agents):
                    if not legal[i, playing[s, i]]:
                        playing[s, i] = np.argmax(legal[i])
                checked[s] = True
            game.step(env, playing[s], env_rng, team_rewards)
            total += team_rewards[0]
            steps += 1
            if game.done(env):
                break
        returns[e] = total
        lengths[e] = steps


@dataclass(frozen=True)
class EpisodeStats:
    """Undiscounted return and length of each episode played."""

    returns: np.ndarray
    lengths: np.ndarray


def evaluate(spec: GameSpec, policy: np.ndarray, episodes: int, rng) -> EpisodeStats:
    """Play ``episodes`` episodes of ``spec`` with the fixed greedy ``policy`` (one joint
    action per state index), the game's randomness drawn from ``rng``."""
    spec.require_one_team("evaluate")
    returns, lengths = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
    loop = specialise(evaluate_episodes, game=spec.kernels)
    counts = spec.action_counts.copy()  # writable: the type every loop is compiled for
    loop(spec.new_env(), policy, counts, int(episodes), spec.max_steps, rng, returns, lengths)
    return EpisodeStats(returns, lengths)


class TabularRun:
    """One tabular learner training on one game: its tables, first visits and streams.

    ``train`` continues where the last call stopped, so a run can stop at checkpoints to
    evaluate its greedy policy and go on with the same streams.
    """

    def __init__(
        self,
        spec: GameSpec,
        config: TabularConfig,
        env_rng: np.random.Generator,
        agent_rng: np.random.Generator,
    ) -> None:
        spec.require_one_team("TabularRun")
        self.spec, self.config = spec, config
        self.params = config.params()
        self.counts = spec.action_counts.copy()
        self.tables = init_tables(config, spec.n_states, self.counts)
        self.seen = np.zeros(spec.n_states, dtype=np.bool_)
        self.env = spec.new_env()
        self.env_rng, self.agent_rng = env_rng, agent_rng
        self._loop = specialise(train_episodes, game=spec.kernels, learner=config.kernels)

    def train(self, episodes: int) -> int:
        """Learn for ``episodes`` more episodes; returns the environment steps taken."""
        return int(
            self._loop(
                self.env,
                self.tables,
                self.params,
                self.counts,
                self.seen,
                int(episodes),
                self.spec.max_steps,
                self.env_rng,
                self.agent_rng,
            )
        )

    def greedy_policy(self) -> np.ndarray:
        """The greedy joint action of every state index: (n_states, n_agents)."""
        return greedy_policy(self.config, self.tables, self.counts)
