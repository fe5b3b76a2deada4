"""A deep learner's gradient step takes the intra-op threads its work pays for."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep import threads  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition  # noqa: E402


@pytest.fixture
def four_threads():
    before = torch.get_num_threads()
    torch.set_num_threads(4)
    yield
    torch.set_num_threads(before)


def test_one_thread_per_share_of_work_within_what_the_process_allows() -> None:
    per = threads.WORK_PER_THREAD
    assert threads.step_threads(0, 8) == 1
    assert threads.step_threads(per - 1, 8) == 1
    assert threads.step_threads(3 * per, 8) == 3
    assert threads.step_threads(3 * per, 2) == 2
    assert threads.step_threads(100 * per, 1) == 1


def test_the_work_is_the_batch_through_every_weight_once() -> None:
    """Two agents, 5 inputs -> 4 hidden -> 3 actions, VDN: (5*4 + 4*3) weights an agent,
    each used once by each of the batch's 10 samples of each of 2 seeds."""
    config = DeepConfig(hidden=4, batch_size=10, buffer_size=10, step="autograd")
    seeds = [np.random.SeedSequence(k) for k in range(2)]
    model = ValueDecomposition([3, 3], 5, config, seeds)
    assert threads.step_work(model) == 2 * 2 * (5 * 4 + 4 * 3) * 10


def test_the_block_sets_the_threads_and_restores_them(four_threads) -> None:
    with threads.intra_op_threads(1):
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == 4


def test_small_and_fused_models_step_on_one_thread_large_ones_on_more(
    four_threads, monkeypatch
) -> None:
    seeds = [np.random.SeedSequence(0)]
    fused = ValueDecomposition([3, 3], 5, DeepConfig(step="fused"), seeds)
    small = ValueDecomposition([3, 3], 5, DeepConfig(step="autograd"), seeds)
    assert fused.step_threads() == small.step_threads() == 1
    monkeypatch.setattr(threads, "WORK_PER_THREAD", 1)  # any work pays for every thread
    large = ValueDecomposition([3, 3], 5, DeepConfig(step="autograd"), seeds)
    assert large.step_threads() == 4  # all the process allows


def test_the_agents_step_with_the_chosen_threads(four_threads) -> None:
    """DeepAgent's gradient steps run with its model's threads; the process keeps its own."""
    from cmarlcd.learners.deep.agent import DeepAgent

    config = DeepConfig(batch_size=4, buffer_size=8, train_every=1, step="autograd")
    agent = DeepAgent([2, 2], config, 20, seed=0, n_states=3)
    seen = []
    step = agent.model.td_step
    agent.model.td_step = lambda batch: seen.append(torch.get_num_threads()) or step(batch)
    rng = np.random.default_rng(0)
    for _ in range(10):
        for state in (0, 1):
            agent.observe(state, tuple(int(a) for a in rng.integers(2, size=2)), 1.0)
        agent.end_episode(2, terminated=True)
    assert seen and set(seen) == {agent.model.step_threads()} == {1}
    assert torch.get_num_threads() == 4


def test_a_model_steps_with_its_threads_whoever_calls_it(four_threads) -> None:
    """A step called on the model itself, outside any learner, runs its backward pass and
    Adam on the model's threads (one for a small model); the process keeps its four."""
    config = DeepConfig(batch_size=4, buffer_size=8, step="autograd")
    model = ValueDecomposition([2, 2], 3, config, [np.random.SeedSequence(0)])
    seen = []
    step = model.optimizer.step
    model.optimizer.step = lambda: seen.append(torch.get_num_threads()) or step()
    batch = {
        "state": torch.zeros((1, 4), dtype=torch.int64),
        "actions": torch.zeros((1, 4, 2), dtype=torch.int64),
        "reward": torch.ones((1, 4)),
        "next_state": torch.ones((1, 4), dtype=torch.int64),
        "terminal": torch.ones((1, 4), dtype=torch.bool),
    }
    model.learn(batch)
    assert seen == [model.step_threads()] == [1]
    assert torch.get_num_threads() == 4
