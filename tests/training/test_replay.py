"""The replay ring of B seeds: storage in a ring, sampling with each seed's own stream."""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.deep.replay import compact_int, new_ring, push, push_row, sample, seed_view


def test_the_ring_keeps_the_latest_transitions() -> None:
    ring = new_ring(seeds=2, capacity=3, n_agents=2, width=5, n_states=43)
    view = seed_view(ring, 1)
    for k in range(5):
        push(view, k, np.array([k % 5, 4 - k % 5]), float(k), k + 1, k == 4)
    assert ring.size.tolist() == [0, 3] and ring.position.tolist() == [0, 2]
    assert ring.state[1].tolist() == [3, 4, 2]  # rows 0 and 1 overwritten by the 4th, 5th
    assert ring.next_state[1].tolist() == [4, 5, 3]
    assert ring.actions[1, 1].tolist() == [4, 0] and ring.terminal[1].tolist() == [0, 1, 0]
    assert ring.state.dtype == np.int8 and compact_int(200) == np.int16


def test_a_terminal_row_is_stored_with_zero_features_and_every_action_legal() -> None:
    ring = new_ring(seeds=1, capacity=2, n_agents=2, width=3, n_states=10, n_features=2)
    view = seed_view(ring, 0)
    legal = np.array([[True, False, True], [False, True, True]])
    push_row(view, np.array([0.5, 1.0]), np.array([2.0, 3.0]), legal, np.array([2, 1]), 1.5, False)
    push_row(view, np.array([2.0, 3.0]), np.array([9.0, 9.0]), legal, np.array([0, 0]), 4.0, True)
    assert ring.state[0].tolist() == [[0.5, 1.0], [2.0, 3.0]]
    assert ring.next_state[0].tolist() == [[2.0, 3.0], [0.0, 0.0]]
    assert ring.next_legal[0, 0].tolist() == legal.tolist() and ring.next_legal[0, 1].all()
    assert ring.reward[0].tolist() == [1.5, 4.0] and ring.terminal[0].tolist() == [False, True]


def test_sample_draws_numpy_s_stream_from_the_stored_rows_of_each_seed() -> None:
    capacity, size = 7, np.array([5, 7])
    ring = new_ring(seeds=2, capacity=capacity, n_agents=2, width=100, n_states=100)
    state = np.arange(2 * capacity, dtype=np.int8).reshape(2, capacity)  # rows are distinct
    ring.state[:] = state
    ring.actions[:] = np.stack([state, -state], axis=-1)
    ring.reward[:] = state * 0.5
    ring.next_state[:] = state + 1
    ring.terminal[:] = state % 2 == 0
    ring.size[:] = size
    batch = sample(ring, (np.random.default_rng(3), np.random.default_rng(4)), 20)
    assert batch["state"].dtype == np.int64 and batch["actions"].dtype == np.int64
    assert "next_legal" not in batch  # integer states: the learner keeps their masks
    for k, seed in enumerate((3, 4)):
        picks = np.random.default_rng(seed).integers(0, size[k], 20)  # NumPy, independently
        for name in ("state", "actions", "reward", "next_state", "terminal"):
            assert np.array_equal(batch[name][k], getattr(ring, name)[k][picks]), name


def test_a_seed_with_nothing_stored_draws_nothing() -> None:
    ring = new_ring(seeds=2, capacity=4, n_agents=1, width=2, n_states=4)
    ring.size[:] = [0, 4]
    ring.state[1] = [0, 1, 2, 3]
    first, second = np.random.default_rng(1), np.random.default_rng(2)
    batch = sample(ring, (first, second), 3)
    assert batch["state"][0].tolist() == [0, 0, 0]
    assert first.random() == np.random.default_rng(1).random()  # its stream untouched
