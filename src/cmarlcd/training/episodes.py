"""The generic episode loop: any learner object on any PettingZoo ``ParallelEnv``.

:func:`play_episodes` drives a learner with the object API (``act`` / ``greedy(state,
masks)``, ``observe(state, joint, reward)``, ``end_episode(final_state, terminated)``:
:class:`cmarlcd.learners.tabular.TabularLearner`,
:class:`cmarlcd.learners.deep_agent.DeepAgent`) through any ``ParallelEnv`` whose
``state()`` is an integer or hashable and whose infos may carry ``"action_mask"``. On the
games of :mod:`cmarlcd.games` it learns exactly what the compiled loops of
:mod:`cmarlcd.training.tabular` learn, one Python call per step.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from cmarlcd.training.tabular import EpisodeStats


def shared_reward(rewards: Mapping[str, float]) -> float:
    """The global reward when every agent receives it (as in the DSN)."""
    return float(next(iter(rewards.values())))


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
    continue the environment's own stream."""
    returns, lengths = np.zeros(episodes), np.zeros(episodes, dtype=np.int64)
    terminated = np.zeros(episodes, dtype=np.bool_)
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
            terminated[episode] = any(terminations.values())
        if learn:
            learner.end_episode(final_state=env.state(), terminated=any(terminations.values()))
    return EpisodeStats(returns, lengths, terminated)
