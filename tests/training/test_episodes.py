"""The generic episode loop over copies of an environment played in lockstep."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

from cmarlcd.training.episodes import play_copies, play_episodes
from tests.tiny_env import RandomLengthEnv


class Recorder:
    """A learner that plays a fixed function of the state (its actions do not depend on
    how copies interleave) and records every call, per copy."""

    def __init__(self, batched: bool) -> None:
        self.calls: dict[int, list] = {}
        self.batched_calls = 0
        if batched:
            self.act_many = self._act_many

    def _joint(self, state) -> tuple[int, int]:
        return (int(state) % 2, (int(state) + 1) % 2)

    def act(self, state, masks=None, copy: int = 0):
        return self._joint(state)

    def _act_many(self, states, masks, copies):
        self.batched_calls += 1
        return [self._joint(s) for s in states]

    greedy = act

    def observe(self, state, joint, reward, copy: int = 0) -> None:
        self.calls.setdefault(copy, []).append(("step", int(state), tuple(joint), reward))

    def end_episode(self, final_state=None, terminated=True, copy: int = 0) -> None:
        self.calls.setdefault(copy, []).append(("end", terminated))


def episodes_of(calls: list) -> list[list]:
    """A copy's calls split into episodes."""
    episodes, current = [], []
    for call in calls:
        current.append(call)
        if call[0] == "end":
            episodes.append(current)
            current = []
    assert current == []  # every episode was closed
    return episodes


@pytest.mark.parametrize("batched", [False, True])
def test_each_copy_plays_what_it_plays_alone(batched: bool) -> None:
    """Four copies whose episodes end at different steps: each copy's transitions are
    those of the same environment played alone from the same seed, every episode of the
    budget is played once, and a batched learner is asked once per step."""
    seeds, budget = [11, 12, 13, 14], 40
    learner = Recorder(batched)
    stats = play_copies([RandomLengthEnv() for _ in seeds], learner, budget, seeds=seeds)
    per_copy = {k: episodes_of(calls) for k, calls in learner.calls.items()}
    assert sum(len(e) for e in per_copy.values()) == budget
    assert len(set(stats.lengths.tolist())) > 1  # the copies end at different steps
    assert sorted(len(e) - 1 for eps in per_copy.values() for e in eps) == sorted(stats.lengths)
    for copy, seed in enumerate(seeds):
        alone = Recorder(batched=False)
        play_episodes(RandomLengthEnv(), alone, len(per_copy[copy]), seed=seed)
        assert learner.calls[copy] == alone.calls[0]
    if batched:
        assert learner.batched_calls == max(
            sum(len(e) - 1 for e in eps) for eps in per_copy.values()
        )


def test_statistics_follow_the_episodes_in_the_order_they_started() -> None:
    """Returns are summed per episode, whichever copy played it."""
    learner = Recorder(batched=True)
    stats = play_copies([RandomLengthEnv() for _ in range(3)], learner, 9, seeds=[1, 2, 3])
    first_of_each = [episodes_of(learner.calls[k])[0] for k in range(3)]
    for k, episode in enumerate(first_of_each):  # episodes 0, 1, 2 start on copies 0, 1, 2
        assert stats.returns[k] == pytest.approx(sum(call[3] for call in episode[:-1]))
        assert stats.lengths[k] == len(episode) - 1


def test_more_copies_than_episodes_leaves_the_rest_idle() -> None:
    learner = Recorder(batched=False)
    stats = play_copies([RandomLengthEnv() for _ in range(5)], learner, 2, seeds=range(5))
    assert sorted(learner.calls) == [0, 1] and len(stats.returns) == 2


def test_greedy_play_asks_for_every_live_copy_at_once() -> None:
    class Greedy(Recorder):
        asked: ClassVar[list[int]] = []

        def greedy_many(self, states, masks):
            self.asked.append(len(states))
            return np.array([self._joint(s) for s in states])

    learner = Greedy(batched=False)
    stats = play_copies([RandomLengthEnv() for _ in range(3)], learner, 6, learn=False)
    assert learner.calls == {}  # nothing learned
    assert sum(learner.asked) == stats.lengths.sum()  # one action per step played
    assert learner.asked[0] == 3  # the three copies together


class SometimesOverAtReset(RandomLengthEnv):
    """Episodes of length 1 end at their reset instead: no agent is left to act."""

    def reset(self, seed=None, options=None):
        result = super().reset(seed, options)
        if self.length == 1:
            self.agents = []
        return result


@pytest.mark.parametrize("copies", [1, 3])
def test_an_episode_over_at_its_reset_is_closed_at_once_as_terminated(copies: int) -> None:
    learner = Recorder(batched=False)
    envs = [SometimesOverAtReset() for _ in range(copies)]
    stats = play_copies(envs, learner, 30, seeds=range(copies))
    empty = stats.lengths == 0
    assert empty.any() and (~empty).any()  # both kinds among the 30
    assert stats.terminated[empty].all()
    ends = [call for calls in learner.calls.values() for call in calls if call[0] == "end"]
    assert len(ends) == 30  # each episode closed once, the empty ones too


@pytest.mark.parametrize("copies", [1, 4])
def test_a_budget_of_steps_ends_with_the_episodes_in_play_when_it_is_reached(
    copies: int,
) -> None:
    """Episodes start while fewer than ``steps`` steps have been played in all; those in
    play then run to their end, so the steps played are at least the budget and less than
    it plus one episode per copy; every episode is closed, and each copy plays what it
    plays alone from its seed (the same episodes as a budget of that many episodes)."""
    seeds, budget = list(range(21, 21 + copies)), 101
    learner = Recorder(batched=True)
    stats = play_copies([RandomLengthEnv() for _ in seeds], learner, 0, seeds=seeds, steps=budget)
    played = int(stats.lengths.sum())
    longest = 6  # RandomLengthEnv's episodes last 1 to 6 steps
    assert budget <= played < budget + copies * longest
    per_copy = {k: episodes_of(calls) for k, calls in learner.calls.items()}
    assert sum(len(e) for e in per_copy.values()) == len(stats.lengths)
    assert sum(len(e) - 1 for eps in per_copy.values() for e in eps) == played
    # the same episodes, copy by copy, as a budget of that many episodes
    by_episodes = Recorder(batched=True)
    again = play_copies(
        [RandomLengthEnv() for _ in seeds], by_episodes, len(stats.lengths), seeds=seeds
    )
    assert by_episodes.calls == learner.calls
    np.testing.assert_array_equal(again.lengths, stats.lengths)
