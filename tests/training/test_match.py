"""Two-team matches: the compiled loops against the ParallelEnv loop, memory, bookkeeping."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.games import battlefield, sensor_network
from cmarlcd.learners.tabular.automata import LAOCA, AutomatonConfig
from cmarlcd.learners.tabular.coordination import BATTLEFIELD_CMARLCD, CMARLCDStochastic
from cmarlcd.training import tabular_side as sides_module
from cmarlcd.training.match import Match

SIDE_AGENTS = 6


def new_match(configs, seed: int = 0, episodes: int = 1000) -> Match:
    env, a, b = (np.random.default_rng(seed + k) for k in range(3))
    return Match(battlefield.SPEC, configs, env, (a, b), episodes)


def values(tables) -> np.ndarray:
    return tables.degrees if hasattr(tables, "degrees") else tables.probs


def side_masks(infos, agents) -> list[np.ndarray]:
    return [infos[agent]["action_mask"] for agent in agents]


def play_with_the_parallel_env(learners, episodes: int, env_seed: int) -> None:
    """The generic loop: each side's object-API learner acts from its side's state and
    masks, observes its side's reward, and learns at the end of each episode."""
    env = battlefield.BattlefieldEnv()
    env.np_random = np.random.default_rng(env_seed)  # reset() continues this stream
    agents = [env.possible_agents[:SIDE_AGENTS], env.possible_agents[SIDE_AGENTS:]]
    for _ in range(episodes):
        _, infos = env.reset()
        while env.agents:
            states = [env.state(0), env.state(1)]
            joints = [
                learner.act(state, side_masks(infos, names))
                for learner, state, names in zip(learners, states, agents, strict=True)
            ]
            actions = dict(zip(env.possible_agents, joints[0] + joints[1], strict=True))
            _, rewards, terminations, _, infos = env.step(actions)
            for k, learner in enumerate(learners):
                learner.observe(states[k], joints[k], rewards[agents[k][0]])
        terminated = any(terminations.values())
        for k, learner in enumerate(learners):
            learner.end_episode(env.state(k), terminated)


def test_compiled_match_learns_what_the_parallel_env_loop_learns() -> None:
    episodes = 150
    counts = [SIDE_AGENTS] * SIDE_AGENTS
    learners = [
        CMARLCDStochastic(counts, BATTLEFIELD_CMARLCD, seed=np.random.default_rng(1)),
        LAOCA(counts, AutomatonConfig(), seed=np.random.default_rng(2)),
    ]
    play_with_the_parallel_env(learners, episodes, env_seed=0)
    compiled = new_match((BATTLEFIELD_CMARLCD, AutomatonConfig()))
    compiled.learn(episodes)
    for side, learner in zip((s.data for s in compiled.sides), learners, strict=True):
        index = learner._index  # state -> row, in order of first visit
        assert len(index) > 100 and int(side.used[0]) == len(index)
        for state, row in index.items():
            assert side.rows[state] == row
        used = len(index)
        assert np.array_equal(side.tables.r_max[:used], learner.tables.r_max[:used])
        assert np.array_equal(values(side.tables)[:used], values(learner.tables)[:used])


def test_evaluation_plays_both_greedy_strategies() -> None:
    """The tally equals a plain-Python replay of the learned greedy strategies."""
    configs = (BATTLEFIELD_CMARLCD, AutomatonConfig())
    played = new_match(configs)
    played.learn(300)
    result = played.evaluate(200, np.random.default_rng(9))
    env = battlefield.BattlefieldEnv()
    env.np_random = np.random.default_rng(9)
    wins, turns_of_wins, ties = [0, 0], [0, 0], 0
    for _ in range(200):
        _, infos = env.reset()
        while env.agents:
            joint = []
            sides = (side.data for side in played.sides)
            for k, (side, config) in enumerate(zip(sides, configs, strict=True)):
                row = side.rows[env.state(k)]
                part = np.zeros(SIDE_AGENTS, dtype=np.int64)
                if row < 0:  # never visited: each agent's lowest legal action
                    masks = side_masks(infos, env.possible_agents[6 * k : 6 * k + 6])
                    part[:] = [int(np.argmax(m)) for m in masks]
                else:
                    config.kernels.greedy(side.tables, row, side.counts, part)
                joint += part.tolist()
            _, _, _, _, infos = env.step(dict(zip(env.possible_agents, joint, strict=True)))
        if env.outcome in (battlefield.WIN_0, battlefield.WIN_1):
            wins[env.outcome] += 1
            turns_of_wins[env.outcome] += env.turn
        else:
            ties += 1
    assert result.wins == tuple(wins) and result.ties == ties
    assert result.win_turns == tuple(turns_of_wins)
    assert sum(result.wins) + result.ties == result.episodes == 200


def test_tables_grow_without_changing_what_is_learned(monkeypatch) -> None:
    configs = (BATTLEFIELD_CMARLCD, BATTLEFIELD_CMARLCD)
    roomy = new_match(configs, seed=5)
    roomy.learn(400)
    monkeypatch.setattr(sides_module, "INITIAL_ROWS", 8)  # the minimum: one episode's states
    tight = new_match(configs, seed=5)
    assert tight.sides[0].data.tables[0].shape[0] == battlefield.PAPER.max_turns + 1
    tight.learn(400)
    for a, b in zip((s.data for s in roomy.sides), (s.data for s in tight.sides), strict=True):
        used = int(a.used[0])
        assert used == int(b.used[0]) and b.tables[0].shape[0] >= used
        assert b.tables[0].shape[0] < a.tables[0].shape[0]  # grew only as needed
        assert np.array_equal(a.rows, b.rows)
        assert np.array_equal(a.tables.degrees[:used], b.tables.degrees[:used])


def test_memory_holds_only_visited_states() -> None:
    played = new_match((AutomatonConfig(), AutomatonConfig()))
    played.learn(200)
    for side in range(2):
        visited = played.visited(side)
        assert 0 < visited < battlefield.SPEC.n_states // 100
        rows = played.sides[side].data.tables[0].shape[0]
        assert rows < 2 * visited + sides_module.INITIAL_ROWS


def test_same_seeds_same_match() -> None:
    results = []
    for _ in range(2):
        played = new_match((BATTLEFIELD_CMARLCD, AutomatonConfig()), seed=3)
        played.learn(200)
        results.append(played.evaluate(100, np.random.default_rng(4)))
    assert results[0] == results[1]


def test_a_match_needs_two_teams() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="two teams"):
        Match(sensor_network.SPEC, (AutomatonConfig(), AutomatonConfig()), rng, (rng, rng), 5)
