"""A third game and a fourth learner, defined here, trained by the public training loops.

The game: a three-step cooperative chain. In state ``s`` (0, 1, 2) the two agents advance
only by playing the joint action ``TARGET[s]``, and even then only with probability 0.9;
the last step pays 10, the others 1; any other joint action pays nothing and stays. In
state 1 agent 1 may not play action 2. The optimum returns 12 in 3 steps. Nothing under
``cmarlcd/training`` knows this game or the learner below.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
import pytest
from numba import njit
from pettingzoo.test import parallel_api_test

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.spec import GameKernels, GameSpec
from cmarlcd.learners.automata import LAOCA, AutomatonConfig
from cmarlcd.learners.coordination import CMARLCDStochastic, StochasticConfig
from cmarlcd.learners.policy import greedy_action
from cmarlcd.learners.tabular import TabularConfig, TabularKernels, no_episode_update
from cmarlcd.training import TabularRun, evaluate, play_episodes

# ------------------------------------------------------------- the game, ~30 lines

TARGET = np.array([[0, 0], [2, 1], [1, 2]])
ADVANCE = 0.9


@njit
def chain_reset(env, rng):
    env[0][0] = 0


@njit
def chain_step(env, joint, rng, rewards):
    s = env[0][0]
    rewards[0] = 0.0
    if joint[0] == TARGET[s, 0] and joint[1] == TARGET[s, 1] and rng.random() < ADVANCE:
        env[0][0] = s + 1
        rewards[0] = 10.0 if s == 2 else 1.0


@njit
def chain_state(env, team):
    return env[0][0]


@njit
def chain_done(env):
    return env[0][0] == 3


@njit
def chain_legal(env, masks):
    masks[:] = True
    if env[0][0] == 1:
        masks[1, 2] = False


CHAIN = GameSpec(
    name="chain_v0",
    kernels=GameKernels(chain_reset, chain_step, chain_state, chain_done, chain_legal),
    new_env=lambda: (np.zeros(1, dtype=np.int64),),
    agents=("left", "right"),
    action_counts=np.array([3, 3]),
    n_states=4,
    max_steps=10,
    teams=((0, 1),),
)

# ------------------------------------------- a fourth learner: independent Q-learning


class QTables(NamedTuple):
    q: np.ndarray
    probs: np.ndarray  # unused by the rule; epsilon-greedy is drawn in act
    legal: np.ndarray


class QParams(NamedTuple):
    alpha: float
    gamma: float
    epsilon: float


@njit
def q_init(tables, params, s, legal, counts):
    for i in range(counts.shape[0]):
        tables.legal[s, i] = legal[i]
        tables.q[s, i] = 0.0


@njit
def q_act(tables, params, s, counts, rng, joint):
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.q[s, i], tables.legal[s, i], counts[i])
        if rng.random() < params.epsilon:
            pick = int(rng.random() * counts[i])
            if tables.legal[s, i, pick]:
                joint[i] = pick


@njit
def q_greedy(tables, s, counts, joint):
    for i in range(counts.shape[0]):
        joint[i] = greedy_action(tables.q[s, i], tables.legal[s, i], counts[i])


@njit
def q_observe(tables, params, states, joints, rewards, t, next_s, terminal):
    s = states[t]
    for i in range(joints.shape[1]):
        best = 0.0 if terminal else tables.q[next_s, i].max()
        target = rewards[t] + params.gamma * best
        a = joints[t, i]
        tables.q[s, i, a] += params.alpha * (target - tables.q[s, i, a])


@dataclass(frozen=True)
class QConfig(TabularConfig):
    name: ClassVar[str] = "iql-test"
    display_name: ClassVar[str] = "IQL"
    kernels: ClassVar[TabularKernels] = TabularKernels(
        q_init, q_act, q_greedy, q_observe, no_episode_update
    )
    alpha: float = 0.2
    gamma: float = 0.9
    epsilon: float = 0.3

    def params(self) -> QParams:
        return QParams(self.alpha, self.gamma, self.epsilon)

    def new_tables(self, n_states: int, counts: np.ndarray) -> QTables:
        shape = (n_states, counts.shape[0], int(counts.max()))
        return QTables(np.zeros(shape), np.zeros(shape), np.zeros(shape, dtype=np.bool_))


# ------------------------------------------------------------------------- tests


def test_the_chain_is_a_parallel_env_through_the_generic_wrapper() -> None:
    env = KernelParallelEnv(CHAIN)
    parallel_api_test(env, num_cycles=50)
    observations, infos = env.reset(seed=1)
    assert observations == {"left": 0, "right": 0}
    while env.state() == 0:
        _, rewards, _, _, infos = env.step({"left": 0, "right": 0})
    assert rewards == {"left": 1.0, "right": 1.0}
    assert infos["right"]["action_mask"].tolist() == [1, 1, 0]  # state 1: right may not play 2
    assert infos["left"]["action_mask"].tolist() == [1, 1, 1]


@pytest.mark.parametrize(
    "config", [StochasticConfig(), AutomatonConfig(), QConfig()], ids=lambda c: c.name
)
def test_tabular_learners_solve_the_chain(config) -> None:
    run = TabularRun(CHAIN, config, np.random.default_rng(1), np.random.default_rng(2))
    run.train(3_000)
    policy = run.greedy_policy()
    assert policy[:3].tolist() == TARGET.tolist()
    stats = evaluate(CHAIN, policy, 2_000, np.random.default_rng(3))
    assert (stats.returns == 12.0).all()  # every episode reaches the end
    assert run.tables.legal[1, 1].tolist() == [True, True, False]  # masks read on first visit


@pytest.mark.parametrize(
    ("learner", "config"),
    [
        (CMARLCDStochastic, StochasticConfig()),
        (LAOCA, AutomatonConfig()),
    ],
)
def test_the_compiled_loop_equals_the_parallel_env_loop_with_masks(learner, config) -> None:
    agent = learner(CHAIN.action_counts, config, n_states=CHAIN.n_states, seed=22)
    stats = play_episodes(KernelParallelEnv(CHAIN), agent, 400, seed=11)
    run = TabularRun(CHAIN, config, np.random.default_rng(11), np.random.default_rng(22))
    assert run.train(400) == stats.lengths.sum()
    for ours, theirs in zip(agent.tables, run.tables, strict=True):
        assert np.array_equal(ours, theirs)


def test_vdn_learns_the_chain_through_the_seed_batched_loop() -> None:
    pytest.importorskip("torch")
    from cmarlcd.learners.deep_config import DeepConfig
    from cmarlcd.training.deep import DeepBatch

    config = DeepConfig(buffer_size=2_000, batch_size=64, train_every=8, target_every=64)
    batch = DeepBatch(CHAIN, config, [np.random.SeedSequence(k) for k in range(2)], 1_500)
    finals = {}
    batch.train([], lambda k, budget, table: finals.__setitem__(k, table))
    for k in range(2):
        assert finals[k][:3].tolist() == TARGET.tolist()
        stats = evaluate(CHAIN, finals[k], 500, np.random.default_rng(k))
        assert (stats.returns == 12.0).all()
