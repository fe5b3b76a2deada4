"""Deep CMARL-CD's keyed memory: an episode folded in by the table's rule, once per visit
(a record resets, a tie moves by δ, a lower return moves nothing), the record a maximum,
the estimate a state not kept is compared with, keys of feature vectors, replacement in
a full slot, which visits may need the network's values, and draws over the kept
states."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.learners.deep.degree_memory import (
    KeyedParams,
    features_key,
    find,
    fold_episode,
    may_be_missing,
    memory_view,
    new_memory,
    sample_memory,
)

#: δ 0.05, δ_reset 0.5, c_init 1.5, c in [0.5, 3], γ 0.5, tolerance 0.5.
PARAMS = KeyedParams(0.05, 0.5, 1.5, 0.5, 3.0, 0.5, 0.5, False)
COUNTS = np.array([3, 2])


def fold(memory, states, joints, rewards, *, bases=None, estimates=None, params=PARAMS):
    """Fold one episode of integer states (their index is their key)."""
    states = np.asarray(states, np.int64)
    length = states.shape[0]
    bases = np.full((length, 2, 3), 1.5, np.float32) if bases is None else bases
    estimates = np.full(length, -np.inf) if estimates is None else np.asarray(estimates, float)
    fold_episode(
        memory, states.astype(np.uint64), states, bases, estimates,
        np.asarray(joints, np.int64), np.asarray(rewards, float), COUNTS, length, params,
    )  # fmt: skip


def entry(memory, state: int) -> tuple[float, np.ndarray]:
    slot = find(memory, np.uint64(state))
    assert slot >= 0, f"state {state} is not kept"
    return float(memory.record[slot]), memory.target[slot].copy()


def test_a_first_visit_is_a_record_and_resets_the_degrees_by_the_large_step() -> None:
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [4], [[2, 0]], [6.0])
    record, target = entry(memory, 4)
    assert record == 6.0
    # reset to 1.5, then the taken action +0.5, the others -0.5; agent 1 has 2 actions
    assert target[0].tolist() == [1.0, 1.0, 2.0]
    assert target[1, :2].tolist() == [2.0, 1.0]


def test_returns_are_discounted_backwards_and_each_visit_is_folded_once() -> None:
    """Rewards 1, 2, 4 with γ 0.5 in states 7, 8, 7: returns 1 + 0.5 (2 + 0.5·4) = 3 at
    the first visit of 7, 4 at 8, 4 at the second visit of 7. Backwards: 7 gets its record
    4 (reset), then 3 is below 4 - 0.5: state 7 keeps the one reset."""
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [7, 8, 7], [[0, 0], [1, 1], [2, 1]], [1.0, 2.0, 4.0])
    assert entry(memory, 7)[0] == 4.0 and entry(memory, 8)[0] == 4.0
    assert entry(memory, 7)[1][0].tolist() == [1.0, 1.0, 2.0]
    assert memory.size[0] == 2


def test_a_tie_moves_by_delta_a_lower_return_moves_nothing_and_the_record_is_a_maximum() -> None:
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [3], [[1, 1]], [10.0])  # record 10: agent 0 (1.0, 2.0, 1.0)
    fold(memory, [3], [[1, 1]], [9.6])  # |9.6 - 10| <= 0.5: a tie, +-0.05
    record, target = entry(memory, 3)
    assert record == 10.0
    assert target[0].tolist() == pytest.approx([0.95, 2.05, 0.95])
    fold(memory, [3], [[0, 0]], [9.0])  # below 10 - 0.5: nothing moves
    assert entry(memory, 3)[1] == pytest.approx(target)
    fold(memory, [3], [[0, 0]], [10.5])  # within the tolerance above: a tie, not a record
    assert entry(memory, 3)[0] == 10.0
    fold(memory, [3], [[0, 0]], [12.0])  # a new record: the maximum, and a reset
    record, target = entry(memory, 3)
    assert record == 12.0 and target[0].tolist() == [2.0, 1.0, 1.0]


#: PARAMS with the expectile record: τ 0.9, a step of 0.5, a new record above it by > 2.
EXPECTILE = PARAMS._replace(expectile_record=True, expectile=0.9, margin=2.0, record_step=0.5)


def test_the_expectile_record_moves_at_every_visit_and_a_record_must_pass_the_margin() -> None:
    """Hand-computed, one-step episodes (the return is the reward): the first visit sets
    the record to its return 10 (and resets); 11.5 is above 10 but within the margin and
    outside the tolerance, so no degree moves, and the record rises by 0.5·0.9·1.5 =
    0.675; 10.5 lies within 0.5 of 10.675, a tie (±δ), and the record falls by
    0.5·0.1·0.175 = 0.00875; a lower return 0 moves no degree but pulls the record down
    by 0.5·0.1·10.66625 = 0.5333125; 14 passes 10.1329375 + 2: a new record, a reset,
    and the record rises by only 0.5·0.9·3.8670625, not to 14."""
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [3], [[1, 1]], [10.0], params=EXPECTILE)
    record, reset = entry(memory, 3)
    assert record == 10.0 and reset[0].tolist() == [1.0, 2.0, 1.0]
    fold(memory, [3], [[0, 0]], [11.5], params=EXPECTILE)
    record, target = entry(memory, 3)
    assert record == pytest.approx(10.675) and target[0].tolist() == reset[0].tolist()
    fold(memory, [3], [[1, 1]], [10.5], params=EXPECTILE)
    record, target = entry(memory, 3)
    assert record == pytest.approx(10.66625)
    assert target[0].tolist() == pytest.approx([0.95, 2.05, 0.95])
    fold(memory, [3], [[0, 0]], [0.0], params=EXPECTILE)
    record, unmoved = entry(memory, 3)
    assert record == pytest.approx(10.1329375) and unmoved == pytest.approx(target)
    fold(memory, [3], [[0, 0]], [14.0], params=EXPECTILE)
    record, target = entry(memory, 3)
    assert record == pytest.approx(10.1329375 + 0.45 * 3.8670625)
    assert target[0].tolist() == [2.0, 1.0, 1.0]


def test_a_lucky_draw_sets_the_maximum_but_not_the_expectile_record() -> None:
    """A state whose returns alternate 14 and 0 (the partially stochastic climbing game's
    miscoordinated optimum) a thousand times: the maximum holds 14; the expectile record
    settles near the returns' 0.9-expectile, 14·0.9 / (0.9 + 0.1) = 12.6."""
    maximum = memory_view(new_memory(1, 10, 2, 3), 0)
    expectile = memory_view(new_memory(1, 10, 2, 3), 0)
    small_steps = EXPECTILE._replace(record_step=0.01)
    for visit in range(1000):
        reward = 14.0 if visit % 2 else 0.0
        fold(maximum, [5], [[1, 1]], [reward])
        fold(expectile, [5], [[1, 1]], [reward], params=small_steps)
    assert entry(maximum, 5)[0] == 14.0
    assert entry(expectile, 5)[0] == pytest.approx(12.6, abs=0.3)


def test_degrees_are_clipped_to_their_bounds() -> None:
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [0], [[0, 0]], [1.0])
    for _ in range(40):  # 40 ties: +2.0 on 2.0 and -2.0 on 1.0, clipped to [0.5, 3]
        fold(memory, [0], [[0, 0]], [1.0])
    assert entry(memory, 0)[1][0].tolist() == [3.0, 0.5, 0.5]


def test_a_state_not_kept_is_compared_with_the_estimate_and_starts_from_the_network() -> None:
    params = PARAMS._replace(estimate_unseen=True)
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    bases = np.array([[[2.0, 4.0, 0.0], [1.0, 1.2, 0.0]]], np.float32)
    fold(memory, [5], [[0, 1]], [3.0], bases=bases, estimates=[4.0], params=params)
    assert find(memory, np.uint64(5)) < 0  # below the estimate: not kept
    fold(memory, [5], [[0, 1]], [4.3], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 5)  # a tie with the estimate: from the network, clipped
    assert record == 4.0
    assert target[0].tolist() == pytest.approx([2.05, 2.95, 0.5])
    assert target[1, :2].tolist() == pytest.approx([0.95, 1.25])
    fold(memory, [6], [[0, 1]], [9.0], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 6)  # a record over the estimate: a reset
    assert record == 9.0 and target[0].tolist() == [2.0, 1.0, 1.0]


def returns_2_and_4(params: KeyedParams):
    """A memory that has folded returns 2 and 4 (rewards 0, 4, γ 0.5) and kept nothing
    (both below an estimate of 100)."""
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [1, 2], [[0, 0], [0, 0]], [0.0, 4.0], estimates=[100.0] * 2, params=params)
    assert memory.size[0] == 0
    return memory


def test_a_state_not_kept_ties_its_estimate_within_the_spread_of_the_returns() -> None:
    """``unseen_tolerance`` 1 (tolerance 1e-9): rewards 0, 4 with γ 0.5 fold returns 2
    and 4, both below an estimate of 100 (not kept): count 2, mean 3, spread 1. A return of
    3.6 against an estimate of 4 is then a tie (0.4 <= 1): state 5 enters from the
    network's degrees, moved by δ (at 0 it is below, not kept). With 3.6 folded the spread
    is sqrt(2.24 / 3) = 0.864, and 5.0 against 4 is a new record (1.0 > 0.864). A kept
    state is compared with its exact record by ``tolerance``: 3.6 against 4 is below."""
    params = PARAMS._replace(tolerance=1e-9, estimate_unseen=True, unseen_tolerance=1.0)
    bases = np.array([[[2.0, 1.0, 1.0], [1.0, 1.2, 0.0]]], np.float32)

    memory = returns_2_and_4(params)
    assert memory.returns[0].tolist() == pytest.approx([2.0, 3.0, 2.0, 2.0, 4.0])
    fold(memory, [5], [[1, 0]], [3.6], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 5)
    assert record == 4.0
    assert target[0].tolist() == pytest.approx([1.95, 1.05, 0.95])
    assert target[1, :2].tolist() == pytest.approx([1.05, 1.15])
    fold(memory, [6], [[0, 0]], [5.0], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 6)
    assert record == 5.0 and target[0].tolist() == [2.0, 1.0, 1.0]
    fold(memory, [5], [[0, 1]], [3.6], bases=bases, estimates=[4.0], params=params)
    assert entry(memory, 5)[1] == pytest.approx(np.stack([[1.95, 1.05, 0.95], [1.05, 1.15, 0]]))
    exact = params._replace(unseen_tolerance=0.0)
    memory = returns_2_and_4(exact)
    fold(memory, [5], [[1, 0]], [3.6], bases=bases, estimates=[4.0], params=exact)
    assert find(memory, np.uint64(5)) < 0


def test_the_spread_may_be_the_range_of_the_returns() -> None:
    """``unseen_range``: returns 2 and 4 folded (range 2), ``unseen_tolerance`` 0.2: a
    tolerance of 0.4. Against an estimate of 4, 3.7 ties (state 5 kept, moved by δ); 4.5
    is a new record (state 6 reset), and the range is 2.5 after it: 3.4 is below 4 - 0.5
    (state 7 not kept). By the standard deviation (1) the tolerance would be 0.2 and 3.7
    below."""
    params = PARAMS._replace(
        tolerance=1e-9, estimate_unseen=True, unseen_tolerance=0.2, unseen_range=True
    )
    memory = returns_2_and_4(params)
    for state, g in ((5, 3.7), (6, 4.5), (7, 3.4)):
        fold(memory, [state], [[1, 0]], [g], estimates=[4.0], params=params)
    assert entry(memory, 5)[0] == 4.0 and entry(memory, 5)[1][0].tolist() == pytest.approx(
        [1.45, 1.55, 1.45]
    )
    assert entry(memory, 6)[0] == 4.5 and entry(memory, 6)[1][0].tolist() == [1.0, 2.0, 1.0]
    assert find(memory, np.uint64(7)) < 0
    assert memory.returns[0, 3:].tolist() == [2.0, 4.5]  # 3.4 counted too
    std = params._replace(unseen_range=False)
    by_std = returns_2_and_4(std)
    fold(by_std, [5], [[1, 0]], [3.7], estimates=[4.0], params=std)
    assert find(by_std, np.uint64(5)) < 0


def test_into_an_empty_memory_every_state_is_a_first_visit_once_kept_asked() -> None:
    """``estimate_once_kept``: returns of -3 and -4 (γ 0.5: -3 + 0.5 (-2) = -4 at state 5,
    -2 at state 6) all fall below an estimate of 0, yet folded into an empty memory both
    states are records (reset). The next episode finds the memory keeping states, so its
    new state 7 is compared with the estimate: -1 is below 0, not kept. Under plain
    ``estimate_unseen`` the first episode keeps nothing."""
    params = PARAMS._replace(estimate_unseen=True, estimate_once_kept=True)
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [5, 6], [[1, 0], [2, 1]], [-3.0, -2.0], estimates=[0.0, 0.0], params=params)
    assert entry(memory, 5)[0] == -4.0 and entry(memory, 6)[0] == -2.0
    assert entry(memory, 5)[1][0].tolist() == [1.0, 2.0, 1.0]  # a reset: the record's rule
    fold(memory, [7], [[0, 0]], [-1.0], estimates=[0.0], params=params)
    assert find(memory, np.uint64(7)) < 0 and memory.size[0] == 2
    plain = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(plain, [5, 6], [[1, 0], [2, 1]], [-3.0, -2.0], estimates=[0.0, 0.0],
         params=params._replace(estimate_once_kept=False))  # fmt: skip
    assert plain.size[0] == 0


def test_a_state_below_its_estimate_is_kept_unmoved_when_asked_and_the_rule_goes_on() -> None:
    """``keep_below``: a first return of 3 below the estimate 4 enters with record 3 and
    the network's degrees, clipped and not stepped; a later 3.2 ties it (within 0.5: the
    taken actions +δ, the others -δ); a later 2 is below it and moves nothing; a 9 is a
    new record and resets."""
    params = PARAMS._replace(estimate_unseen=True, keep_below=True)
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    bases = np.array([[[2.0, 4.0, 0.0], [1.0, 1.2, 0.0]]], np.float32)
    fold(memory, [5], [[0, 1]], [3.0], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 5)
    assert record == 3.0
    assert target[0].tolist() == pytest.approx([2.0, 3.0, 0.5])
    assert target[1, :2].tolist() == pytest.approx([1.0, 1.2])
    fold(memory, [5], [[0, 1]], [3.2], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 5)
    assert record == 3.0
    assert target[0].tolist() == pytest.approx([2.05, 2.95, 0.5])
    assert target[1, :2].tolist() == pytest.approx([0.95, 1.25])
    fold(memory, [5], [[2, 0]], [2.0], bases=bases, estimates=[4.0], params=params)
    assert entry(memory, 5)[0] == 3.0
    assert entry(memory, 5)[1][0].tolist() == pytest.approx([2.05, 2.95, 0.5])
    fold(memory, [5], [[2, 0]], [9.0], bases=bases, estimates=[4.0], params=params)
    record, target = entry(memory, 5)
    assert record == 9.0 and target[0].tolist() == [1.0, 1.0, 2.0]


def test_feature_vectors_are_keyed_by_their_bytes_and_a_full_slot_is_replaced() -> None:
    x = np.array([0.5, 1.0, -2.0], np.float32)
    assert features_key(x) == features_key(x.copy())
    assert features_key(x) != features_key(np.array([0.5, 1.0, -2.5], np.float32))
    assert features_key(x) != features_key(x[::-1].copy())
    memory = memory_view(new_memory(1, 1, 2, 3, n_features=3), 0)  # one slot
    rows = np.array([x, 2 * x], np.float32)
    keys = np.array([features_key(rows[0]), features_key(rows[1])], np.uint64)
    for t in range(2):
        fold_episode(
            memory, keys[t : t + 1], rows[t : t + 1], np.full((1, 2, 3), 1.5, np.float32),
            np.full(1, -np.inf), np.zeros((1, 2), np.int64), np.ones(1), COUNTS, 1, PARAMS,
        )  # fmt: skip
    assert memory.size[0] == 1 and find(memory, keys[0]) < 0 and find(memory, keys[1]) == 0
    assert memory.state[0].tolist() == (2 * x).tolist()


def test_draws_are_uniform_over_the_kept_states_with_each_seed_s_stream() -> None:
    memory = new_memory(2, 50, 2, 3)
    fold(memory_view(memory, 0), [3, 30, 40], [[0, 0]] * 3, [1.0, 1.0, 1.0])
    fold(memory_view(memory, 1), [9], [[1, 1]], [2.0])
    batch = sample_memory(memory, [np.random.default_rng(0), np.random.default_rng(1)], 3000)
    assert set(batch["state"][0].tolist()) == {3, 30, 40}
    counts = np.bincount(batch["state"][0], minlength=41)[[3, 30, 40]]
    assert counts.min() > 900  # 1,000 each expected
    assert set(batch["state"][1].tolist()) == {9} and set(batch["record"][1].tolist()) == {2.0}
    again = sample_memory(memory, [np.random.default_rng(0), np.random.default_rng(1)], 3000)
    assert np.array_equal(batch["state"], again["state"])


def test_keys_of_zero_one_features_spread_over_the_slots() -> None:
    """The slot is the key modulo the capacity: 0/1 features (the sensor network's) must
    not crowd into a few slots. 4,096 distinct 12-bit vectors in 40,000 slots: uniform
    hashing leaves about 200 of them sharing a slot (4,096² / 80,000)."""
    vectors = ((np.arange(4096)[:, None] >> np.arange(12)) & 1).astype(np.float32)
    slots = {int(features_key(v)) % 40_000 for v in vectors}
    assert len(slots) > 3_800


def test_only_visits_whose_state_may_be_missing_when_folded_need_the_network() -> None:
    """Capacity 10, states 3 and 4 kept. An episode visits 3, 4, 14 and 5: 3 stays kept
    (no other state of the episode maps to slot 3); 4 is kept now, but 14 shares its slot
    and may replace it during the fold; 14 and 5 are not kept."""
    memory = memory_view(new_memory(1, 10, 2, 3), 0)
    fold(memory, [3, 4], [[0, 0], [0, 0]], [1.0, 1.0])
    keys = np.array([3, 4, 14, 5], np.uint64)
    assert [may_be_missing(memory, keys, 4, t) for t in range(4)] == [False, True, True, True]
    # the same state twice in one episode is no conflict with itself
    twice = np.array([3, 3], np.uint64)
    assert [may_be_missing(memory, twice, 2, t) for t in range(2)] == [False, False]


def test_a_set_of_two_ways_keeps_two_states_of_one_set_and_replaces_the_least_recent() -> None:
    """Capacity 10 in sets of 2: 5 sets, a key's set is key mod 5. States 2, 7 and 12 all
    map to set 2 (slots 4 and 5). Direct-mapped, 2 and 12 would share slot 2; here 2 and 7
    are both kept. After episodes visiting 2, then 7, then 2 again, 7 is the entry visited
    least recently, so 12 replaces 7 and 2 stays."""
    memory = memory_view(new_memory(1, 10, 2, 3, ways=2), 0)
    fold(memory, [2], [[0, 0]], [1.0])
    fold(memory, [7], [[0, 0]], [1.0])
    assert find(memory, np.uint64(2)) == 4 and find(memory, np.uint64(7)) == 5
    fold(memory, [2], [[0, 0]], [0.0])  # below the record: no degree moves, but a visit
    fold(memory, [12], [[1, 1]], [1.0])
    assert find(memory, np.uint64(7)) < 0
    assert find(memory, np.uint64(2)) == 4 and find(memory, np.uint64(12)) == 5
    assert memory.size[0] == 2 and entry(memory, 12)[1][0].tolist() == [1.0, 2.0, 1.0]


def test_with_sets_a_visit_may_be_missing_when_another_state_of_its_set_is_in_the_episode() -> None:
    """Sets of 2 in 10 slots: 3 and 8 share set 3, 4 is alone in set 4."""
    memory = memory_view(new_memory(1, 10, 2, 3, ways=2), 0)
    fold(memory, [3, 4], [[0, 0], [0, 0]], [1.0, 1.0])
    keys = np.array([3, 8, 4], np.uint64)
    assert [may_be_missing(memory, keys, 3, t) for t in range(3)] == [True, True, False]


def test_a_capacity_is_rounded_up_to_whole_sets() -> None:
    memory = new_memory(1, 10, 2, 3, ways=4)
    assert memory.key.shape == (1, 12) and memory.visited.shape == (1, 12)
    assert new_memory(1, 10, 2, 3).visited.shape == (1, 0)  # direct-mapped: no stamps
