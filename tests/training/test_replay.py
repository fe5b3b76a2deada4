"""Replay buffers of B seeds: storage in a ring, sampling with each seed's own stream."""

from __future__ import annotations

import numpy as np

from cmarlcd.training.replay import compact_int, new_batch, new_buffers, replay_sample, store


def test_the_ring_keeps_the_latest_transitions() -> None:
    buffer = new_buffers(seeds=2, capacity=3, n_agents=2, n_states=43, width=5)
    for k in range(5):
        store(buffer, 1, k, np.array([k % 5, 4 - k % 5]), float(k), k + 1, k == 4)
    assert buffer.size.tolist() == [0, 3] and buffer.position.tolist() == [0, 2]
    assert buffer.state[1].tolist() == [3, 4, 2]  # rows 0 and 1 overwritten by the 4th, 5th
    assert buffer.next_state[1].tolist() == [4, 5, 3]
    assert buffer.actions[1, 1].tolist() == [4, 0] and buffer.terminal[1].tolist() == [0, 1, 0]
    assert buffer.state.dtype == np.int8 and compact_int(200) == np.int16


def test_replay_sample_draws_numpy_s_stream_from_the_stored_rows_of_each_seed() -> None:
    capacity, size = 7, np.array([5, 7])
    buffer = new_buffers(seeds=2, capacity=capacity, n_agents=2, n_states=100, width=100)
    state = np.arange(2 * capacity, dtype=np.int8).reshape(2, capacity)  # rows are distinct
    buffer.state[:] = state
    buffer.actions[:] = np.stack([state, -state], axis=-1)
    buffer.reward[:] = state * 0.5
    buffer.next_state[:] = state + 1
    buffer.terminal[:] = state % 2 == 0
    buffer.size[:] = size
    out = new_batch(2, 20, 2)
    replay_sample(buffer, (np.random.default_rng(3), np.random.default_rng(4)), 20, out)
    for k, seed in enumerate((3, 4)):
        picks = np.random.default_rng(seed).integers(0, size[k], 20)  # NumPy, independently
        for stored, drawn in zip(buffer[:5], out, strict=True):
            assert np.array_equal(drawn[k], stored[k][picks])
