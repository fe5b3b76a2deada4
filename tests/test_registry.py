"""Every registered game and learner works through the public protocols."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd import registry
from cmarlcd.training import TabularRun, evaluate
from cmarlcd.training.match import Match

TABULAR = [name for name in registry.LEARNERS if not registry.needs_torch(name)]
ONE_TEAM = [name for name, spec in registry.GAMES.items() if spec().n_teams == 1]
TWO_TEAMS = [name for name, spec in registry.GAMES.items() if spec().n_teams == 2]


@pytest.mark.parametrize("game", ONE_TEAM)
@pytest.mark.parametrize("learner", TABULAR)
def test_every_tabular_learner_trains_and_plays_every_game(game: str, learner: str) -> None:
    spec = registry.GAMES[game]()
    run = TabularRun(spec, registry.LEARNERS[learner], *np.random.default_rng([1, 2]).spawn(2))
    steps = run.train(50)
    assert 50 <= steps <= 50 * spec.max_steps
    stats = evaluate(spec, run.greedy_policy(), 20, np.random.default_rng(3))
    assert stats.lengths.min() >= 1 and stats.lengths.max() <= spec.max_steps


@pytest.mark.slow
@pytest.mark.parametrize("game", TWO_TEAMS)
@pytest.mark.parametrize("learner", TABULAR)
def test_every_tabular_learner_plays_both_sides_of_every_two_team_game(
    game: str, learner: str
) -> None:
    spec, config = registry.GAMES[game](), registry.LEARNERS[learner]
    rngs = np.random.default_rng([1, 2]).spawn(3)
    match = Match(spec, (config, config), rngs[0], rngs[1:], 50)
    match.learn()
    assert 50 <= match.turns <= 50 * spec.max_steps
    result = match.evaluate(20, np.random.default_rng(3))
    assert sum(result.wins) + result.ties == 20 and result.turns >= 20


def test_learners_are_found_by_their_own_names() -> None:
    for name, config in registry.LEARNERS.items():
        assert config.name == name and registry.is_paper_setting(config)
        assert registry.learner_config(name, {}) == config
    assert registry.display_name("la-oca") == "LA-OCA" and registry.needs_torch("qmix")
    with pytest.raises(ValueError, match="unknown 'dqn'; available: cmarl-cd, la-oca"):
        registry.require_learner("dqn")
