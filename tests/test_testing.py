"""The conformance checks of :mod:`cmarlcd.testing`, on every registered game and learner,
and on broken ones they must catch."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from cmarlcd import registry
from cmarlcd.games.battlefield import BattlefieldEnv
from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.matrix import MatrixGameEnv, climbing_game
from cmarlcd.games.sensor_network import SensorNetworkEnv
from cmarlcd.learners.tabular.coordination import (
    StochasticConfig,
    coordination_end_episode,
    coordination_init,
)
from cmarlcd.learners.tabular.protocol import TabularKernels, no_step_update
from cmarlcd.testing import CHAIN, DUEL, check_game, check_learner
from cmarlcd.testing.envs import check_observations

HAS_TORCH = importlib.util.find_spec("torch") is not None
GAME_ENVS = {
    "SensorNetworkEnv": SensorNetworkEnv,
    "BattlefieldEnv": BattlefieldEnv,
    "MatrixGameEnv": lambda render_mode=None: MatrixGameEnv(climbing_game(), render_mode),
}


@pytest.mark.parametrize("game", list(registry.stochastic_games()))
def test_every_registered_game_passes_every_check(game: str) -> None:
    check_game(registry.stochastic_games()[game]())


@pytest.mark.parametrize("env", list(GAME_ENVS))
def test_every_games_own_env_class_passes_every_check(env: str) -> None:
    check_game(GAME_ENVS[env])


@pytest.mark.parametrize("spec", [CHAIN, DUEL], ids=lambda s: s.name)
def test_the_test_games_pass_every_check(spec) -> None:
    check_game(spec)


def test_observations_are_numpy_integers_of_the_spaces_dtype() -> None:
    env = SensorNetworkEnv()
    observations, _ = env.reset(seed=0)
    for agent, observation in observations.items():
        assert type(observation) is np.int64
        assert observation.dtype == env.observation_space(agent).dtype
    assert type(env.state()) is np.int64
    assert type(BattlefieldEnv().reset(seed=0)[0]["side0_marine_0"]) is np.int64


class PythonIntEnv(KernelParallelEnv):
    """The bug this catches: observations as Python ints, off their ``Discrete`` dtype."""

    def _observations(self, states):
        return {agent: int(value) for agent, value in super()._observations(states).items()}


def test_check_game_catches_observations_off_their_spaces_dtype() -> None:
    with pytest.raises(AssertionError, match="int64"):
        check_observations(PythonIntEnv(CHAIN), seed=0)
    with pytest.raises((AssertionError, AttributeError), match="dtype"):  # AEC api_test
        check_game(lambda render_mode=None: PythonIntEnv(CHAIN, render_mode))


@pytest.mark.parametrize("name", list(registry.REPEATED_LEARNERS))
def test_every_repeated_game_learner_passes_every_check(name: str) -> None:
    check_learner(registry.REPEATED_LEARNERS[name])


@pytest.mark.slow
@pytest.mark.parametrize(
    "name", [n for n in registry.LEARNERS if HAS_TORCH or not registry.needs_torch(n)]
)
def test_every_stochastic_game_learner_passes_every_check(name: str) -> None:
    check_learner(registry.LEARNERS[name])


def careless_greedy(tables, s, counts, joint):
    """A greedy rule that forgets the masks: the highest degree, legal or not."""
    for i in range(counts.shape[0]):
        joint[i] = int(np.argmax(tables.degrees[s, i, : counts[i]]))


@dataclass(frozen=True)
class CarelessConfig(StochasticConfig):
    name: ClassVar[str] = "careless"
    kernels: ClassVar[TabularKernels] = TabularKernels(
        coordination_init,
        StochasticConfig.kernels.act,
        __import__("numba").njit(careless_greedy),
        no_step_update,
        coordination_end_episode,
    )


def test_check_learner_catches_a_greedy_rule_that_ignores_the_masks() -> None:
    with pytest.raises(AssertionError, match="greedy action"):
        check_learner(CarelessConfig(), episodes=100)


def test_check_learner_refuses_what_is_no_learner() -> None:
    with pytest.raises(AssertionError, match="no learner config"):
        check_learner(object())
