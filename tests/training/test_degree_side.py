"""Deep CMARL-CD's keyed memory in the compiled loop and the object API: what an episode
folds in (the network's degrees and record estimate at a state not kept, computed as the
networks compute them), and a tie fitted many times moving the network by δ, not more."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig  # noqa: E402
from cmarlcd.learners.deep.degree_agent import DegreeAgent  # noqa: E402
from cmarlcd.learners.deep.degree_memory import features_key, find  # noqa: E402
from cmarlcd.learners.tabular.automata import AutomatonConfig  # noqa: E402
from cmarlcd.testing import CHAIN, DUEL  # noqa: E402
from cmarlcd.training.match import Match  # noqa: E402

SMALL = DeepCMARLCDConfig(
    buffer_size=1000, batch_size=8, train_every=4, target_every=8, tolerance=0.5,
    unseen_record="estimate",
)  # fmt: skip


def duel_side(config: DeepCMARLCDConfig):
    env, a, b = (np.random.default_rng(k) for k in range(3))
    return Match(DUEL, (config, AutomatonConfig()), env, (a, b), 5).sides[0]


def test_a_state_not_kept_folds_in_from_the_networks_degrees_and_record_estimate() -> None:
    """One visit whose return ties the record network's estimate at its features: it is
    kept with that record, and its targets are the degree network's clipped degrees there,
    the taken action +δ and the others -δ (the compiled forward passes agree with the
    networks). A second, far better visit elsewhere is a new record: a reset."""
    side = duel_side(SMALL)
    data, model = side.data, side.model
    x = np.array([[0.5, 0.25], [1.0, 0.0]], np.float32)
    data.obs[:2] = x
    with torch.no_grad():
        degrees = model.agents(torch.from_numpy(x)[None])[0].clamp(0.5, 3.0).numpy()
        estimate = model.record(torch.from_numpy(x)[None])[0].numpy().astype(float)
    data.joints[:2] = [[2, 0], [1, 1]]
    # visit 1 (folded first) a record far above; visit 0: G_0 = r_0 + 0.9 G_1 ties
    data.rewards[1] = estimate[1] + 10.0
    data.rewards[0] = estimate[0] - 0.9 * data.rewards[1]
    side.kernels.end_episode(data, 2)
    memory = data.replay.memory
    tied, record = (
        find(memory, np.uint64(features_key(x[0]))),
        find(memory, np.uint64(features_key(x[1]))),
    )
    assert tied >= 0 and record >= 0 and memory.size[0] == 2
    assert memory.record[tied] == pytest.approx(estimate[0], abs=1e-4)
    assert memory.record[record] == pytest.approx(estimate[1] + 10.0, abs=1e-4)
    step = np.where(np.arange(3) == 2, 0.05, -0.05)
    expected = np.clip(degrees[0, 0] + step, 0.5, 3.0)
    assert memory.target[tied, 0] == pytest.approx(expected, abs=1e-5)
    assert memory.target[record, 0].tolist() == [1.0, 2.0, 1.0]  # c_init 1.5 +- 0.5
    assert memory.state[tied].tolist() == x[0].tolist()


def test_under_the_table_s_rule_a_first_visit_is_always_a_record() -> None:
    side = duel_side(replace(SMALL, unseen_record="first-visit"))
    data = side.data
    data.obs[:1] = [[0.0, 0.75]]
    data.joints[:1] = [[0, 2]]
    data.rewards[:1] = [-100.0]
    side.kernels.end_episode(data, 1)
    memory = data.replay.memory
    slot = find(memory, np.uint64(features_key(data.obs[0])))
    assert slot >= 0
    assert memory.record[slot] == -100.0
    assert memory.target[slot, 1].tolist() == [1.0, 1.0, 2.0]


def test_a_tie_fitted_many_times_moves_the_degree_network_by_delta() -> None:
    """One state, three actions: a record (return 5) then a tie (5 again), each fitted by
    400 gradient steps. The network ends where the table is: the record's reset (the
    taken action 2.0), then δ = 0.05 further, however many steps fit the tie."""
    config = DeepCMARLCDConfig(batch_size=16, buffer_size=64, lr=1e-2, tolerance=0.5)
    agent = DegreeAgent([3], config, 10, n_states=1, seed=0)

    def episode_then_fit() -> np.ndarray:
        agent.observe(0, (1,), 5.0)
        agent.end_episode()
        for _ in range(400):
            agent.model.learn(agent._replay_batch())
        return agent.degrees(0)[0]

    after_record = episode_then_fit()
    after_tie = episode_then_fit()
    moved = after_tie[1] - after_record[1]
    assert after_record == pytest.approx([1.0, 2.0, 1.0], abs=0.01)
    assert moved == pytest.approx(0.05, abs=0.01)


def test_a_state_replaced_during_the_fold_is_read_from_the_network_not_stale_data() -> None:
    """A memory of one slot. `first` is kept; an episode at another state `other` is
    left out (below its estimate); then an episode visits `first` and `second`: folded
    backwards, `second` replaces `first`, whose own visit then re-enters as a state not
    kept, compared with the estimate at `first` (a tie), not with what an earlier
    episode left in the scratch."""
    side = duel_side(replace(SMALL, buffer_size=1, batch_size=1))
    data, model = side.data, side.model
    first, other, second = np.array([[0.5, 0.25], [0.0, 1.0], [1.0, 0.0]], np.float32)
    with torch.no_grad():
        estimate = model.record(torch.from_numpy(np.stack([first, other, second]))[None])[0]
        degrees = model.agents(torch.from_numpy(first)[None, None])[0, 0].clamp(0.5, 3.0)
    for obs, reward in ((first, estimate[0] + 5.0), (other, estimate[1] - 5.0)):
        data.obs[:1], data.joints[:1], data.rewards[:1] = [obs], [[0, 0]], [float(reward)]
        side.kernels.end_episode(data, 1)
    memory = data.replay.memory
    assert find(memory, np.uint64(features_key(first))) == 0  # `other` was left out
    data.obs[:2] = [first, second]
    data.joints[:2] = [[2, 2], [1, 1]]
    data.rewards[1] = float(estimate[2]) + 5.0  # a new record at `second`
    data.rewards[0] = float(estimate[0]) - 0.9 * data.rewards[1]  # G at `first` = estimate
    side.kernels.end_episode(data, 2)
    assert find(memory, np.uint64(features_key(first))) == 0  # `first` is back, from the tie
    assert memory.record[0] == pytest.approx(float(estimate[0]), abs=1e-4)
    step = np.where(np.arange(3) == 2, 0.05, -0.05)
    assert memory.target[0, 0] == pytest.approx(
        np.clip(degrees[0].numpy() + step, 0.5, 3), abs=1e-5
    )


def test_acting_from_the_memory_reads_its_degrees_where_it_keeps_the_state() -> None:
    """``act_from="memory"``, T = 0.01 (a draw from softmax(c/T) is then the argmax): at a
    kept state the agents act on the memory's degrees, set here where the network would
    not put them (agent 0 prefers action 0, agent 1 action 1); at a state not kept they
    act on the network's, as the compiled forward pass computes them."""
    side = duel_side(
        replace(SMALL, act_from="memory", unseen_record="first-visit", temperature=0.01)
    )
    data, model = side.data, side.model
    kept, unkept = np.array([[0.5, 0.25], [1.0, 0.0]], np.float32)
    data.obs[:1], data.joints[:1], data.rewards[:1] = [kept], [[2, 2]], [1.0]
    side.kernels.end_episode(data, 1)
    memory = data.replay.memory
    slot = find(memory, np.uint64(features_key(kept)))
    memory.target[slot, 0] = [3.0, 0.5, 0.5]
    memory.target[slot, 1] = [0.5, 3.0, 0.5]
    data.obs[:2] = [kept, unkept]
    data.legal[:2] = True
    rng, joint = np.random.default_rng(0), np.zeros(2, np.int64)
    side.kernels.act(data, 0, rng, joint)
    assert joint.tolist() == [0, 1]
    with torch.no_grad():
        degrees = model.agents(torch.from_numpy(unkept)[None, None])[0, 0].clamp(0.5, 3.0)
    side.kernels.act(data, 1, rng, joint)
    assert joint.tolist() == degrees.argmax(dim=-1).tolist()


def test_the_object_api_acts_from_the_memory_where_it_keeps_the_state() -> None:
    """A record at state 0 (action 1 taken): the memory holds the table's reset, [1, 2, 1],
    and the greedy action there is 1 whatever the untrained network says; at state 1,
    never met, the degrees are the network's."""
    config = DeepCMARLCDConfig(act_from="memory", unseen_record="first-visit")
    agent = DegreeAgent([3], config, 10, n_states=2, seed=0)
    network_before = agent.degrees(0)
    agent.observe(0, (1,), 5.0)
    agent.end_episode()
    assert agent.degrees(0)[0].tolist() == [1.0, 2.0, 1.0]
    assert agent.greedy(0) == (1,)
    with torch.no_grad():
        network = agent.model.agents(torch.tensor([[1]]))[0, 0].clamp(0.5, 3.0).numpy()
    assert agent.degrees(1) == pytest.approx(network)
    assert not np.allclose(network_before[0], [1.0, 2.0, 1.0])


def test_the_object_api_keeps_colliding_states_in_the_ways_of_a_set() -> None:
    """A memory of 2 slots: states 1 and 3 share a slot direct-mapped (the second
    replaces the first), and share the one set of 2 ways (both are kept)."""

    def kept(ways: int) -> list[bool]:
        config = DeepCMARLCDConfig(
            act_from="memory", unseen_record="first-visit", buffer_size=2, batch_size=1,
            ways=ways,
        )  # fmt: skip
        agent = DegreeAgent([3], config, 10, n_states=5, seed=0)
        for state in (1, 3):
            agent.observe(state, (1,), 5.0)
            agent.end_episode()
        return [agent.degrees(state)[0].tolist() == [1.0, 2.0, 1.0] for state in (1, 3)]

    assert kept(1) == [False, True]
    assert kept(2) == [True, True]


def test_the_object_api_acts_from_the_memory_on_feature_states() -> None:
    """Feature inputs are keyed by a 64-bit hash, half of which do not fit a signed
    integer: a kept state's greedy action comes from the memory whatever its key."""
    config = DeepCMARLCDConfig(act_from="memory", unseen_record="first-visit")
    agent = DegreeAgent([3], config, 10, state_dim=2, seed=0)
    states = [np.array([k, 1.0], np.float32) for k in range(8)]
    assert max(int(features_key(s)) for s in states) >= 2**63  # a key above int64's range
    for state in states:
        agent.observe(state, (2,), 5.0)
        agent.end_episode()
    assert [agent.greedy(s) for s in states] == [(2,)] * len(states)


def test_many_states_at_once_act_as_one_at_a_time() -> None:
    """``greedy_many`` gives each state's greedy action (memory and network states
    mixed), and ``act_many`` draws what the same states drawn one by one would."""
    config = DeepCMARLCDConfig(act_from="memory", unseen_record="first-visit")
    agent = DegreeAgent([3, 2], config, 10, n_states=6, seed=0)
    agent.observe(4, (2, 0), 5.0)
    agent.end_episode()
    states, masks = [0, 4, 5], [None, None, [np.array([1, 1, 0]), np.array([0, 1])]]
    many = agent.greedy_many(states, masks)
    one_by_one = [agent.greedy(s, m) for s, m in zip(states, masks, strict=True)]
    assert [tuple(row) for row in many] == one_by_one
    assert tuple(many[1]) == (2, 0)  # from the memory
    twin = DegreeAgent([3, 2], config, 10, n_states=6, seed=0)
    twin.observe(4, (2, 0), 5.0)
    twin.end_episode()
    drawn = agent.act_many(states, masks, [0, 1, 2])
    assert drawn == [twin.act(s, m) for s, m in zip(states, masks, strict=True)]
    assert drawn[2][0] != 2 and drawn[2][1] == 1  # masked actions never drawn


def test_each_copy_folds_its_own_episode() -> None:
    """Visits of two interleaved episodes: each copy's episode is folded when it ends,
    as if played alone (state 1's record from copy 0's visit, state 2's from copy 1's)."""
    config = DeepCMARLCDConfig(act_from="memory", unseen_record="first-visit")
    agent = DegreeAgent([3], config, 10, n_states=3, seed=0)
    agent.observe(1, (0,), 1.0, copy=0)
    agent.observe(2, (2,), 1.0, copy=1)
    agent.end_episode(copy=1)
    assert agent.degrees(2)[0].tolist() == [1.0, 1.0, 2.0]
    assert agent.degrees(1)[0].tolist() != [2.0, 1.0, 1.0]  # copy 0's episode still open
    agent.end_episode(copy=0)
    assert agent.degrees(1)[0].tolist() == [2.0, 1.0, 1.0]
    assert agent.episode == 2


def test_the_greedy_table_takes_each_kept_state_s_action_from_the_memory() -> None:
    """Index inputs: the executed greedy table is the networks' with each kept state's
    row from its memory degrees over its masks (an illegal best action skipped; lowest
    index on ties); rows of states not kept are the networks'."""
    from cmarlcd.training.deep_replay import KEYED

    config = DeepCMARLCDConfig(act_from="memory")
    replay = KEYED.new(config, 1, np.array([3, 3]), CHAIN, 0)  # CHAIN: 4 states
    memory = replay.memory
    for slot, state, degrees in (
        (0, 2, [[3.0, 1.0, 0.5], [1.0, 2.0, 2.0]]),
        (1, 0, [[0.5, 0.5, 0.5], [0.5, 0.5, 3.0]]),
    ):
        memory.filled[0, slot], memory.state[0, slot] = True, state
        memory.order[0, memory.size[0]] = slot
        memory.size[0] += 1
        memory.target[0, slot] = degrees
    legal = np.ones((1, 4, 2, 3), bool)
    legal[0, 2, 0, 0] = False  # state 2: agent 0's best action is illegal
    network = np.full((1, 4, 2), 7)
    table = KEYED.greedy_table(replay, network.copy(), legal, config)
    assert table[0, 2].tolist() == [1, 1]  # agent 0: 1.0 > 0.5 among legal; agent 1: tie -> 1
    assert table[0, 0].tolist() == [0, 2]
    assert table[0, [1, 3]].tolist() == [[7, 7], [7, 7]]
    acting_from_network = KEYED.greedy_table(replay, network.copy(), legal, SMALL)
    assert (acting_from_network == 7).all()


def test_acting_from_the_memory_on_state_indices_in_the_compiled_loop() -> None:
    """One-hot inputs (CHAIN's 4 states), T = 0.01: at a kept state the side acts on the
    memory's degrees (set where the network would not put them), elsewhere on its row of
    the networks' table; then a whole learning stage runs and every kept state's greedy
    action is its memory's argmax."""
    from cmarlcd.training.deep import DeepBatch

    config = DeepCMARLCDConfig(
        act_from="memory", unseen_record="first-visit", temperature=0.01,
        buffer_size=64, batch_size=8, train_every=4,
    )  # fmt: skip
    batch = DeepBatch(CHAIN, config, [np.random.SeedSequence(3)], 300)
    data = batch.group.views[0].data
    memory = data.replay.memory
    memory.filled[2], memory.key[2] = True, np.uint64(2)
    memory.target[2] = [[0.5, 3.0, 0.5], [0.5, 0.5, 3.0]]
    rng, joint = np.random.default_rng(0), np.zeros(2, np.int64)
    kernels = batch.group.views[0].kernels
    kernels.act(data, 2, rng, joint)
    assert joint.tolist() == [1, 2]
    kernels.act(data, 0, rng, joint)
    assert joint.tolist() == np.clip(data.values[0], 0.5, 3.0).argmax(axis=-1).tolist()
    memory.filled[2] = False
    batch.train([300], lambda k, point, policy: None)
    tables = batch.greedy_tables()[0]
    kept = memory.order[: memory.size[0]]
    assert len(kept) > 0
    for slot in kept:
        state = int(memory.state[slot])
        masked = np.where(batch.group.legal[0, state], memory.target[slot], -np.inf)
        assert tables[state].tolist() == masked.argmax(axis=-1).tolist()


def test_where_every_return_is_negative_only_the_once_kept_estimate_learns() -> None:
    """Rewards of -1 at every step: the record network starts near 0, above every return,
    so under ``estimate`` no visit is ever kept and the network never takes a step; under
    ``estimate-once-kept`` the first episode enters the empty memory whole and the
    networks are fitted from then on."""

    def play(unseen: str) -> DegreeAgent:
        config = replace(SMALL, unseen_record=unseen)
        agent = DegreeAgent([2, 2], config, 50, state_dim=3, seed=0)
        rng = np.random.default_rng(0)
        for _ in range(20):
            for _ in range(5):
                state = rng.random(3).astype(np.float32)
                agent.observe(state, agent.act(state), -1.0)
            agent.end_episode()
        return agent

    assert play("estimate").stored == 0
    assert play("estimate-once-kept").stored >= 5
