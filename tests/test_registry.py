"""Every registered game and learner works through the public protocols."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd import registry
from cmarlcd.runs import identity
from cmarlcd.training import TabularRun, evaluate
from cmarlcd.training.match import Match

TABULAR = [name for name in registry.LEARNERS if not registry.needs_torch(name)]
ONE_TEAM = [name for name, spec in registry.stochastic_games().items() if spec().n_teams == 1]
TWO_TEAMS = [name for name, spec in registry.stochastic_games().items() if spec().n_teams == 2]


@pytest.mark.parametrize("game", ONE_TEAM)
@pytest.mark.parametrize("learner", TABULAR)
def test_every_tabular_learner_trains_and_plays_every_game(game: str, learner: str) -> None:
    spec = registry.stochastic_games()[game]()
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
    spec, config = registry.stochastic_games()[game](), registry.LEARNERS[learner]
    rngs = np.random.default_rng([1, 2]).spawn(3)
    match = Match(spec, (config, config), rngs[0], rngs[1:], 50)
    match.learn()
    assert 50 <= match.turns <= 50 * spec.max_steps
    result = match.evaluate(20, np.random.default_rng(3))
    assert sum(result.wins) + result.ties == 20 and result.turns >= 20


def test_learners_are_found_by_their_own_names() -> None:
    for name, config in registry.LEARNERS.items():
        assert config.name == name and registry.is_paper_setting(config)
        assert registry.learner_config(name, identity(config)) == config
    assert registry.display_name("la-oca") == "LA-OCA" and registry.needs_torch("qmix")
    with pytest.raises(ValueError, match="unknown 'dqn'; available: cmarl-cd, la-oca"):
        registry.require_learner("dqn")


def test_each_learner_is_registered_once_under_the_name_of_every_form_it_takes() -> None:
    from cmarlcd.experiments.tournament import paper_learners
    from cmarlcd.learners.deep.config import DeepLearnerConfig

    for name, learner in registry.REGISTRY.items():
        forms = [learner.stochastic, learner.repeated, *learner.presets.values()]
        forms = [form for form in forms if form is not None]
        assert forms, name
        assert all(form.name == name for form in forms), name
        assert learner.needs_torch == all(isinstance(form, DeepLearnerConfig) for form in forms)
    battlefield_players = list(registry.learners_on(registry.BATTLEFIELD))
    assert battlefield_players == ["cmarl-cd", "la-oca", "vdn", "qmix", "deep-cmarl-cd"]
    assert list(paper_learners()) == ["cmarl-cd", "la-oca", "vdn", "qmix"]  # the paper's


def test_each_game_is_registered_once_with_a_way_to_play_it() -> None:
    from cmarlcd.experiments import compare

    for name, game in registry.GAMES.items():
        assert game.name == name and (game.spec is not None or game.make is not None)
    assert registry.repeated_games() == compare.GAMES  # the comparison's columns
    for game in registry.repeated_games().values():
        for size in game.sizes or (None,):
            made = game.make(size, np.random.default_rng(0))
            assert int(np.prod(made.action_counts)) == game.joint_actions(size)
