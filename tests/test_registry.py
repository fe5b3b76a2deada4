"""Every registered game and learner works through the public protocols."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from cmarlcd import registry
from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.training import TabularRun, evaluate

TABULAR = [name for name in registry.LEARNERS if not registry.needs_torch(name)]


@pytest.mark.parametrize("game", list(registry.GAMES))
def test_every_game_is_a_parallel_env(game: str) -> None:
    parallel_api_test(KernelParallelEnv(registry.GAMES[game]()), num_cycles=30)


@pytest.mark.parametrize("game", list(registry.GAMES))
@pytest.mark.parametrize("learner", TABULAR)
def test_every_tabular_learner_trains_and_plays_every_game(game: str, learner: str) -> None:
    spec = registry.GAMES[game]()
    run = TabularRun(spec, registry.LEARNERS[learner], *np.random.default_rng([1, 2]).spawn(2))
    steps = run.train(50)
    assert 50 <= steps <= 50 * spec.max_steps
    stats = evaluate(spec, run.greedy_policy(), 20, np.random.default_rng(3))
    assert stats.lengths.min() >= 1 and stats.lengths.max() <= spec.max_steps


def test_learners_are_found_by_their_own_names() -> None:
    for name, config in registry.LEARNERS.items():
        assert config.name == name and registry.is_paper_setting(config)
        assert registry.learner_config(name, {}) == config
    assert registry.display_name("la-oca") == "LA-OCA" and registry.needs_torch("qmix")
    with pytest.raises(ValueError, match="unknown 'dqn'; available: cmarl-cd, la-oca"):
        registry.require_learner("dqn")
