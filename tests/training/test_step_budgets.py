"""Learning budgets counted in environment steps (``train --steps``): where a run stops,
that it stops there however it is called, and ε annealed over steps."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.experiments.episodic import EpisodicRun
from cmarlcd.games.foraging import Foraging
from cmarlcd.learners.policy import annealed_epsilon
from cmarlcd.learners.tabular.coordination import StochasticConfig
from cmarlcd.training import TabularRun

SPEC = Foraging(5, 2, 1).spec()


def new_run(seed: int = 0) -> TabularRun:
    return TabularRun(SPEC, StochasticConfig(), *(np.random.default_rng(seed + k) for k in (0, 1)))


def lengths_one_by_one(run: TabularRun, goal: int) -> list[int]:
    """Episodes learnt one at a time until ``goal`` steps: each one's length."""
    lengths = []
    while run.turns < goal:
        lengths.append(run.train(1))
    return lengths


@pytest.mark.parametrize("goal", [1, 49, 50, 51, 777, 3000])
def test_a_step_budget_ends_at_the_end_of_the_episode_it_is_reached_in(goal) -> None:
    reference = new_run()
    lengths = lengths_one_by_one(reference, goal)
    run = new_run()
    episodes = run.train_until_steps(goal)
    assert episodes == len(lengths) and run.turns == sum(lengths)
    assert sum(lengths[:-1]) < goal <= sum(lengths)  # the first episode end at or past it
    assert np.array_equal(run.greedy_policy(), reference.greedy_policy())


def test_step_budgets_in_pieces_equal_one_budget() -> None:
    whole, pieces = new_run(3), new_run(3)
    whole.train_until_steps(2500)
    for goal in (10, 600, 601, 1900, 2500):
        pieces.train_until_steps(goal)
    assert whole.turns == pieces.turns
    assert np.array_equal(whole.greedy_policy(), pieces.greedy_policy())


def test_a_run_of_steps_is_another_run_and_an_episode_run_keeps_its_key() -> None:
    learner = StochasticConfig()
    episodes = EpisodicRun(learner, (100,), 10, 2, 10)
    steps = EpisodicRun(learner, (100,), 10, 2, 10, unit="steps")
    assert "unit" not in episodes.to_config()  # keys stored before step budgets unchanged
    assert steps.to_config()["unit"] == "steps"
    assert EpisodicRun.from_config(steps.to_config()) == steps
    assert EpisodicRun.from_config(episodes.to_config()) == episodes
    # curve points at 50 and 100 (10 episodes each), the checkpoint at 100 (10 more)
    assert steps.work(50) == 100 / 50 + 10 * 2 + 10 and episodes.work(50) == 100 + 10 * 2 + 10


def test_deep_exploration_anneals_over_steps_where_the_budget_counts_steps() -> None:
    pytest.importorskip("torch")
    from cmarlcd.learners.deep.config import DeepConfig
    from cmarlcd.training.deep import DeepBatch
    from cmarlcd.training.deep_kernels import EPISODES, TURNS, exploration

    config = DeepConfig(buffer_size=500, batch_size=16, train_every=20, target_every=40)
    seeds = [np.random.SeedSequence(1)]
    for unit, counter in (("steps", TURNS), ("episodes", EPISODES)):
        batch = DeepBatch(SPEC, config, seeds, 1000, unit=unit)
        side = batch.group.views[0].data
        for done in (0, 399, 799, 900):
            side.counters[TURNS], side.counters[EPISODES] = 0, 0
            side.counters[counter] = done
            expected = annealed_epsilon(
                done + 1, 1000, config.eps_start, config.eps_end, config.anneal_fraction,
                config.eps_after,
            )  # fmt: skip
            assert exploration(side) == pytest.approx(expected)


def test_deep_seeds_learn_to_the_step_budget() -> None:
    pytest.importorskip("torch")
    from cmarlcd.learners.deep.config import DeepConfig
    from cmarlcd.training.deep import DeepBatch

    config = DeepConfig(buffer_size=500, batch_size=16, train_every=20, target_every=40)
    seeds = [np.random.SeedSequence(k) for k in range(3)]
    batch = DeepBatch(SPEC, config, seeds, 700, unit="steps")
    seen: dict[int, list[int]] = {0: [], 1: [], 2: []}
    batch.train([200, 700], lambda k, point, policy: seen[k].append(point))
    for play in batch.plays:
        assert 700 <= play.turns < 700 + SPEC.max_steps and play.learned_turns(700)
    assert all(points == [200, 700] for points in seen.values())
