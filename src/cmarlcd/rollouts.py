"""Playing episodes: a generic loop for any PettingZoo ParallelEnv, compiled loops for the DSN.

The generic loop (:func:`play_episodes`) drives a tabular learner through any
``ParallelEnv`` whose ``state()`` is an integer or hashable and whose infos may carry
``"action_mask"``. The compiled loops (:func:`dsn_train`, :func:`dsn_evaluate`) run the
same learner kernels against the DSN's compiled transition. With the same seeds both
paths consume the random streams in the same order (the environment's generator for
starts and target moves, the learner's for actions), so they learn the same tables.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.policy import (
    annealed_epsilon,
    epsilon_greedy,
    greedy_actions,
    sample_joint_action,
)
from cmarlcd.learners.stochastic import TabularTables, update_from_episode


def shared_reward(rewards: Mapping[str, float]) -> float:
    """The global reward when every agent receives it (as in the DSN)."""
    return float(next(iter(rewards.values())))


@dataclass(frozen=True)
class EpisodeStats:
    """Undiscounted return and length of each episode played."""

    returns: np.ndarray
    lengths: np.ndarray


def play_episodes(
    env,
    learner: Any,
    episodes: int,
    *,
    learn: bool = True,
    seed: int | None = None,
    global_reward: Callable[[Mapping[str, float]], float] = shared_reward,
) -> EpisodeStats:
    """Play ``episodes`` episodes of ``env``: sampled actions and learning when ``learn``,
    greedy actions otherwise. ``seed`` seeds the first ``env.reset``; later episodes
    continue the environment's own stream.

    ``learner`` is a tabular learner or a :class:`cmarlcd.deep_training.DeepAgent`:
    anything with ``act``/``greedy(state, masks)``, ``observe(state, joint, reward)`` and
    ``end_episode(final_state, terminated)``."""
    returns, lengths = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
    for episode in range(episodes):
        _, infos = env.reset(seed=seed if episode == 0 else None)
        agents = list(env.possible_agents)
        while env.agents:
            state = env.state()
            masks = (
                [infos[a]["action_mask"] for a in agents]
                if "action_mask" in infos[agents[0]]
                else None
            )
            joint = learner.act(state, masks) if learn else learner.greedy(state, masks)
            _, rewards, terminations, _, infos = env.step(dict(zip(agents, joint, strict=True)))
            reward = global_reward(rewards)
            if learn:
                learner.observe(state, joint, reward)
            returns[episode] += reward
            lengths[episode] += 1
        if learn:
            learner.end_episode(final_state=env.state(), terminated=any(terminations.values()))
    return EpisodeStats(returns, lengths)


# ------------------------------------------------------------- compiled DSN loops


@njit(cache=True)
def dsn_train(
    values: np.ndarray,
    probs: np.ndarray,
    legal: np.ndarray,
    counts: np.ndarray,
    r_max: np.ndarray,
    params,
    episodes: int,
    env_rng,
    agent_rng,
) -> int:
    """Algorithm 2 (or LA-OCA, by ``params.kind``) on the DSN for ``episodes`` episodes.

    Returns the number of environment steps taken."""
    states = np.zeros(dsn.MAX_STEPS, dtype=np.int64)
    joints = np.zeros((dsn.MAX_STEPS, dsn.N_SENSORS), dtype=np.int64)
    rewards = np.zeros(dsn.MAX_STEPS)
    targets = np.zeros(2, dtype=np.int64)
    energy = np.zeros(2, dtype=np.int64)
    individual = np.zeros(dsn.N_SENSORS)
    total_steps = 0
    for _ in range(episodes):
        dsn.dsn_reset(targets, energy, env_rng)
        length = 0
        while length < dsn.MAX_STEPS:
            s = dsn.dsn_state(targets)
            sample_joint_action(probs[s], counts, agent_rng, joints[length])
            rewards[length] = dsn.dsn_step(targets, energy, joints[length], env_rng, individual)
            states[length] = s
            length += 1
            if dsn.done(targets):
                break
        update_from_episode(
            states, joints, rewards, length, values, probs, legal, counts, r_max, params
        )
        total_steps += length
    return total_steps


@njit(cache=True)
def dsn_evaluate(policy: np.ndarray, episodes: int, env_rng) -> tuple[int, float, int]:
    """Play ``episodes`` episodes with the fixed joint policy ``policy[state]``.

    Returns (successful episodes, total undiscounted return, total steps); an episode
    succeeds when its return is the optimum, 42, reached in exactly 3 steps.
    """
    targets = np.zeros(2, dtype=np.int64)
    energy = np.zeros(2, dtype=np.int64)
    individual = np.zeros(dsn.N_SENSORS)
    successes, total_return, total_steps = 0, 0.0, 0
    for _ in range(episodes):
        dsn.dsn_reset(targets, energy, env_rng)
        episode_return, steps = 0.0, 0
        while steps < dsn.MAX_STEPS:
            joint = policy[dsn.dsn_state(targets)]
            episode_return += dsn.dsn_step(targets, energy, joint, env_rng, individual)
            steps += 1
            if dsn.done(targets):
                break
        successes += episode_return == dsn.OPTIMAL_RETURN and steps == dsn.OPTIMAL_STEPS
        total_return += episode_return
        total_steps += steps
    return successes, total_return, total_steps


def greedy_policy(tables: TabularTables) -> np.ndarray:
    """The greedy joint action of every state: shape (n_states, n_agents)."""
    return np.stack(
        [
            greedy_actions(tables.values[s], tables.legal[s], tables.counts)
            for s in range(tables.n_states)
        ]
    )


def dsn_tables(params) -> TabularTables:
    """Fresh tables for the DSN: 43 state indices (42 + terminal), every action legal."""
    tables = TabularTables(dsn.N_STATE_INDICES, dsn.ACTION_COUNTS.copy(), params)
    tables.init_all()
    return tables


def train_dsn(tables: TabularTables, episodes: int, env_rng, agent_rng) -> int:
    """Continue training ``tables`` on the DSN with the compiled loop; returns the steps."""
    return dsn_train(
        tables.values,
        tables.probs,
        tables.legal,
        tables.counts,
        tables.r_max,
        tables.params,
        int(episodes),
        env_rng,
        agent_rng,
    )


# ------------------------------------------------- compiled DSN loop for VDN / QMIX


@njit(cache=True)
def dsn_collect(
    greedy: np.ndarray,
    steps: int,
    total_episodes: int,
    schedule: tuple,
    envs: tuple,
    buffer: tuple,
    env_rngs,
    act_rngs,
) -> None:
    """Step each of B DSN copies ``steps`` steps with ε-greedy actions (eq. 18).

    ``greedy[b, s]`` is seed b's greedy joint action in state s (the networks change only
    between calls). ``envs`` = (targets, energy, clock, episodes), each with a leading seed
    axis; a seed that has finished its ``total_episodes`` stops. Transitions go into seed
    b's ring ``buffer`` = (state, actions, reward, next_state, terminal, position, size).
    ``env_rngs[b]`` and ``act_rngs[b]`` are seed b's own generators, so the seeds are
    independent and are stepped one after the other (the order does not matter).
    """
    targets, energy, clock, episodes = envs
    b_state, b_actions, b_reward, b_next, b_terminal, position, size = buffer
    counts = dsn.ACTION_COUNTS
    capacity = b_state.shape[1]
    individual = np.zeros(dsn.N_SENSORS)
    joint = np.zeros(dsn.N_SENSORS, dtype=np.int64)
    for b in range(targets.shape[0]):
        for _ in range(steps):
            if episodes[b] >= total_episodes:
                break
            s = dsn.dsn_state(targets[b])
            eps = annealed_epsilon(episodes[b] + 1, total_episodes, *schedule)
            epsilon_greedy(greedy[b, s], counts, eps, act_rngs[b], joint)
            reward = dsn.dsn_step(targets[b], energy[b], joint, env_rngs[b], individual)
            clock[b] += 1
            terminal = dsn.done(targets[b])
            p = position[b]
            b_state[b, p], b_reward[b, p], b_terminal[b, p] = s, reward, terminal
            b_actions[b, p] = joint
            b_next[b, p] = dsn.dsn_state(targets[b])
            position[b] = (p + 1) % capacity
            size[b] = min(size[b] + 1, capacity)
            if terminal or clock[b] >= dsn.MAX_STEPS:
                episodes[b] += 1
                clock[b] = 0
                if episodes[b] < total_episodes:
                    dsn.dsn_reset(targets[b], energy[b], env_rngs[b])


@njit(cache=True)
def replay_sample(buffer: tuple, rngs, batch_size: int, out: tuple) -> None:
    """Draw ``batch_size`` stored transitions per seed, uniformly with replacement, with
    seed b's generator ``rngs[b]`` (the same draws as ``rngs[b].integers(0, size,
    batch_size)`` in NumPy), into ``out`` = (state, actions, reward, next_state,
    terminal), each with a leading seed axis. ``buffer`` as in :func:`dsn_collect`."""
    b_state, b_actions, b_reward, b_next, b_terminal, _, size = buffer
    o_state, o_actions, o_reward, o_next, o_terminal = out
    for b in range(b_state.shape[0]):
        picks = rngs[b].integers(0, size[b], batch_size)
        for n in range(batch_size):
            k = picks[n]
            o_state[b, n], o_next[b, n] = b_state[b, k], b_next[b, k]
            o_reward[b, n], o_terminal[b, n] = b_reward[b, k], b_terminal[b, k]
            o_actions[b, n] = b_actions[b, k]
