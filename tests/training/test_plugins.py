"""A learner defined here, in a test file, trained by the public training loops on the
chain of :mod:`cmarlcd.testing` (a three-step cooperative chain with a state-dependent
mask; the optimum returns 12 in 3 steps). Nothing under ``cmarlcd/training`` knows the
game or the learner, and the learner passes the checks a plug-in author runs.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
import pytest
from numba import njit

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.learners.policy import greedy_action
from cmarlcd.learners.tabular.automata import AutomatonConfig
from cmarlcd.learners.tabular.coordination import StochasticConfig
from cmarlcd.learners.tabular.protocol import TabularConfig, TabularKernels, no_episode_update
from cmarlcd.testing import CHAIN, check_learner
from cmarlcd.testing.games import CHAIN_TARGET
from cmarlcd.training import TabularRun, evaluate

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


@pytest.mark.slow
def test_a_plug_in_learner_passes_the_conformance_checks() -> None:
    check_learner(QConfig())


def test_the_chain_speaks_through_the_generic_wrapper() -> None:
    env = KernelParallelEnv(CHAIN)
    observations, infos = env.reset(seed=1)
    assert observations == {"agent_0": 0, "agent_1": 0}
    while env.state() == 0:
        _, rewards, _, _, infos = env.step({"agent_0": 0, "agent_1": 0})
    assert rewards == {"agent_0": 1.0, "agent_1": 1.0}
    assert infos["agent_1"]["action_mask"].tolist() == [1, 1, 0]  # state 1: not action 2
    assert infos["agent_0"]["action_mask"].tolist() == [1, 1, 1]


@pytest.mark.parametrize(
    "config", [StochasticConfig(), AutomatonConfig(), QConfig()], ids=lambda c: c.name
)
def test_tabular_learners_solve_the_chain(config) -> None:
    run = TabularRun(CHAIN, config, np.random.default_rng(1), np.random.default_rng(2))
    run.train(3_000)
    policy = run.greedy_policy()
    assert policy[:3].tolist() == CHAIN_TARGET.tolist()
    stats = evaluate(CHAIN, policy, 2_000, np.random.default_rng(3))
    assert (stats.returns == 12.0).all()  # every episode reaches the end
    assert run.tables.legal[1, 1].tolist() == [True, True, False]  # masks read on first visit


def test_vdn_learns_the_chain_through_the_seed_batched_loop() -> None:
    pytest.importorskip("torch")
    from cmarlcd.learners.deep.config import DeepConfig
    from cmarlcd.training.deep import DeepBatch

    config = DeepConfig(buffer_size=2_000, batch_size=64, train_every=8, target_every=64)
    batch = DeepBatch(CHAIN, config, [np.random.SeedSequence(k) for k in range(2)], 1_500)
    finals = {}
    batch.train([], lambda k, budget, policy: finals.__setitem__(k, policy.table))
    for k in range(2):
        assert finals[k][:3].tolist() == CHAIN_TARGET.tolist()
        stats = evaluate(CHAIN, finals[k], 500, np.random.default_rng(k))
        assert (stats.returns == 12.0).all()


@pytest.mark.slow
def test_a_plug_in_s_types_never_reach_a_shared_on_disk_cache(tmp_path) -> None:
    """After the plug-in learner played both sides of a match (check_learner above), a
    process that cannot import this test module still compiles and plays every loop:
    no kernel cached on disk was compiled for the plug-in's tables."""
    check_learner(QConfig())
    script = (
        "from cmarlcd import registry\n"
        "from cmarlcd.testing.learners import _check_two_team_play\n"
        "_check_two_team_play(registry.LEARNERS['cmarl-cd'], 20)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]


PLUG_IN_FIRST = """
import importlib.util, sys
import numpy as np
spec = importlib.util.spec_from_file_location("plug_in", sys.argv[1])
module = importlib.util.module_from_spec(spec)
sys.modules["plug_in"] = module
spec.loader.exec_module(module)
from cmarlcd.testing import CHAIN
from cmarlcd.training import TabularRun
run = TabularRun(CHAIN, module.QConfig(), np.random.default_rng(1), np.random.default_rng(2))
print(run.train(200))
"""


@pytest.mark.slow
def test_a_plug_in_whose_kernels_allocate_trains_in_the_compiled_loop_first() -> None:
    """The plug-in's observe calls ``.max()`` (numba allocates for it) under plain
    ``@njit``: the loop must compile it as such even when no object API compiled it
    before (a fresh process whose first call is the compiled loop)."""
    done = subprocess.run(
        [sys.executable, "-c", PLUG_IN_FIRST, __file__], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert int(done.stdout) >= 200
