"""Seed-batched VDN / QMIX training on the DSN, and the ParallelEnv agent."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.compiled import kernel  # noqa: E402
from cmarlcd.experiments import episodic, settings_of  # noqa: E402
from cmarlcd.experiments import sensor_network as sn  # noqa: E402
from cmarlcd.games import sensor_network as dsn  # noqa: E402
from cmarlcd.games.spec import GameKernels, GameSpec  # noqa: E402
from cmarlcd.learners.deep.agent import DeepAgent  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig  # noqa: E402
from cmarlcd.training.deep import DeepBatch  # noqa: E402
from cmarlcd.training.episodes import play_episodes  # noqa: E402

SMALL = DeepConfig(buffer_size=2_000, batch_size=100, train_every=50, target_every=200)


@pytest.mark.parametrize("algorithm", ["vdn", "qmix"])
def test_seed_b_of_a_batch_equals_that_seed_alone(algorithm: str) -> None:
    small = DeepConfig(
        mixer=algorithm, buffer_size=1_000, batch_size=50, train_every=50, target_every=200
    )
    sweep = sn.DsnSweep(
        learners=(small,), episodes=(150,), runs=3, eval_episodes=200, curve_points=3
    )
    specs = sweep.specs()
    seeds = [s.seed_sequence() for s in specs]
    batch = episodic.run_batch(sn.DSN_GAME, settings_of(specs[0]), seeds)
    alone = episodic.run(sn.DSN_GAME, settings_of(specs[1]), specs[1].seed_sequence())
    assert batch[1]["policy"] == alone["policy"]
    assert batch[1]["checkpoints"] == alone["checkpoints"]
    assert [c[:2] for c in batch[1]["curve"]] == [c[:2] for c in alone["curve"]]
    assert batch[0]["policy"] != batch[1]["policy"]  # seeds are independent


def test_gradient_and_target_cadence(monkeypatch) -> None:
    seeds = [np.random.SeedSequence(0)]
    run = DeepBatch(dsn.SPEC, SMALL, seeds, total_episodes=60)
    trained, synced = [], []
    monkeypatch.setattr(run.model, "td_step", lambda batch: trained.append(run.env_steps))
    monkeypatch.setattr(run.model, "sync_target", lambda: synced.append(run.env_steps))
    run.train([], lambda *args: None)
    # a gradient step every 50 env steps once 100 transitions exist; a target copy every 200
    assert trained[0] == 100 and set(np.diff(trained)) == {50}
    assert synced == list(range(200, run.env_steps + 1, 200))


def test_every_seed_stops_at_its_episode_budget() -> None:
    run = DeepBatch(dsn.SPEC, SMALL, [np.random.SeedSequence(k) for k in range(3)], 25)
    seen = []
    run.train([10], lambda k, budget, policy: seen.append((k, budget, policy.table.shape)))
    assert run.episodes.tolist() == [25, 25, 25]
    assert sorted(seen) == [(k, b, (43, 12)) for k in range(3) for b in (10, 25)]


def test_deep_agent_learns_on_the_parallel_env() -> None:
    agent = DeepAgent(dsn.ACTION_COUNTS, SMALL, 20, n_states=dsn.N_STATE_INDICES, seed=0)
    stats = play_episodes(dsn.SensorNetworkEnv(), agent, 20, seed=1)
    assert agent.steps == stats.lengths.sum() and agent.episode == 20
    assert agent.stored == min(agent.steps, SMALL.buffer_size)
    greedy = play_episodes(dsn.SensorNetworkEnv(), agent, 3, learn=False, seed=2)
    assert greedy.lengths.min() >= 1


def test_deep_agent_with_feature_states_and_masks() -> None:
    """A generic state vector and legal masks: masked actions are never taken."""
    agent = DeepAgent([3, 2], SMALL, 10, state_dim=4, seed=0)
    masks = [np.array([1, 0, 1]), np.array([1, 1])]
    for _ in range(300):
        joint = agent.act(np.ones(4), masks)
        assert joint[0] != 1
        agent.observe(np.ones(4), joint, 1.0)
    agent.end_episode(np.ones(4), terminated=False)
    assert agent.greedy(np.ones(4), masks)[0] != 1


# A two-step game whose second state forbids agent 0's action 1; the game counts the
# times it is played anyway.


@kernel
def trap_reset(env, rng):
    env[0][0] = 0


@kernel
def trap_step(env, joint, rng, rewards):
    rewards[0] = 0.0
    if env[0][0] == 1 and joint[0] == 1:
        env[0][1] += 1
    env[0][0] += 1


@kernel
def trap_state(env, team):
    return env[0][0]


@kernel
def trap_done(env):
    return env[0][0] == 2


@kernel
def trap_legal(env, masks):
    masks[:] = True
    if env[0][0] == 1:
        masks[0, 1] = False


TRAP = GameSpec(
    "trap_v0",
    GameKernels(trap_reset, trap_step, trap_state, trap_done, trap_legal),
    lambda: (np.zeros(2, dtype=np.int64),),
    ("agent_0", "agent_1"),
    np.array([2, 2]),
    n_states=3,
    max_steps=5,
    teams=((0, 1),),
)


def test_a_greedy_action_is_legal_from_the_first_visit_of_a_state() -> None:
    """The greedy action of a state met for the first time in the middle of a collection
    call keeps to its masks (it used to be the argmax over every action, read before the
    masks were)."""
    greedy = DeepConfig(
        eps_start=0.0, eps_end=0.0, eps_after=0.0, buffer_size=100, batch_size=10,
        train_every=4, target_every=8,
    )  # fmt: skip
    for seed in range(10):
        run = DeepBatch(TRAP, greedy, [np.random.SeedSequence(seed)], 20)
        run.train([], lambda *args: None)
        assert run.plays[0].env[0][1] == 0, f"seed {seed}: an illegal action was played"


def test_exploration_draws_only_legal_actions() -> None:
    """ε = 1: every action a uniform draw over the state's legal actions."""
    explore = DeepConfig(
        eps_start=1.0, eps_end=1.0, eps_after=1.0, buffer_size=100, batch_size=10,
        train_every=4, target_every=8,
    )  # fmt: skip
    run = DeepBatch(TRAP, explore, [np.random.SeedSequence(3)], 200)
    run.train([], lambda *args: None)
    assert run.plays[0].env[0][1] == 0, "an illegal action was explored"


def test_a_seed_learns_what_it_learns_alone_when_another_seed_finishes_short_of_a_batch() -> None:
    """Seeds finish their episodes at different turns. Here seed 5 finishes with 210
    transitions stored, fewer than a batch of 220, while others go on: they take their
    gradient steps as they would alone (a finished seed's ring does not hold them back)."""
    config = DeepConfig(buffer_size=1_000, batch_size=220, train_every=10, target_every=50)
    final: dict[tuple[str, int], np.ndarray] = {}

    def keep(where: str, k0: int = 0):
        return lambda k, budget, policy: final.__setitem__((where, k0 + k), policy.table.copy())

    together = DeepBatch(dsn.SPEC, config, [np.random.SeedSequence(k) for k in range(6)], 6)
    together.train([], keep("together"))
    sizes = together.group.ring.size
    assert sizes.min() < config.batch_size < sizes.max()  # the case arises
    for k in range(6):
        DeepBatch(dsn.SPEC, config, [np.random.SeedSequence(k)], 6).train([], keep("alone", k))
        assert np.array_equal(final["together", k], final["alone", k]), f"seed {k}"


@pytest.mark.parametrize("name", ["vdn", pytest.param("deep-cmarl-cd", marks=pytest.mark.slow)])
def test_evaluating_on_the_way_leaves_a_feature_reading_seed_as_it_was(name: str) -> None:
    """A seed that reads the game's features has no table: its own side plays its greedy
    strategy on a game of its own, between learning turns (in the middle of an episode
    too), and what it learns is what it learns without the evaluations."""
    from dataclasses import replace

    from cmarlcd import registry

    spec = dsn.make_spec(2, 2, 1)
    config = replace(
        registry.require_learner(name),
        buffer_size=500,
        batch_size=32,
        train_every=7,
        target_every=63,
    )

    def learn(checkpoints: list[int]) -> tuple[list, list]:
        batch = DeepBatch(spec, config, [np.random.SeedSequence(0)], 120)
        assert batch.inputs == "features"
        played = []

        def evaluate(k: int, budget: int, policy) -> None:
            assert policy.table is None
            played.append(policy.evaluate(15, np.random.default_rng(budget)).lengths.sum())

        batch.train(checkpoints, evaluate)
        return [p.detach().clone() for p in batch.model.parameters()], played

    quiet, _ = learn([])
    busy, played = learn(list(range(1, 120, 3)))
    assert len(played) == 41 and all(steps >= 15 for steps in played)
    assert all(torch.equal(a, b) for a, b in zip(quiet, busy, strict=True))


def test_greedy_tables_read_the_masks_met_since_the_last_step(monkeypatch) -> None:
    """A model that holds a copy of the masks (as one on a GPU does) is told of the masks
    read since its last gradient step before a greedy table is read: state 1's illegal
    action is never greedy once state 1 has been met."""
    config = DeepConfig(buffer_size=100, batch_size=10, train_every=4, target_every=8)
    illegal = []
    for seed in range(6):
        run = DeepBatch(TRAP, config, [np.random.SeedSequence(seed)], 20)
        model, group = run.group.model, run.group

        def keep_a_copy(legal, model=model) -> None:
            type(model).set_state_legal(model, legal.clone())

        monkeypatch.setattr(model, "set_state_legal", keep_a_copy)
        model.set_state_legal(torch.from_numpy(group.legal))

        def evaluate(k, episodes, policy, group=group) -> None:
            if group.seen[k, 1]:
                illegal.append(int(policy.table[1, 0]) == 1)

        run.train(list(range(1, 21)), evaluate)
    assert illegal and not any(illegal)


def test_deep_agent_acts_for_many_copies_with_one_forward_pass() -> None:
    """``greedy_many`` is each state's greedy action; ``act_many`` draws what the states
    drawn one by one would; each copy's step becomes a transition to that copy's next
    state, and its episode's end to a terminal one."""
    agent = DeepAgent([3, 2], SMALL, 10, n_states=6, seed=0)
    twin = DeepAgent([3, 2], SMALL, 10, n_states=6, seed=0)
    states, masks = [0, 4, 5], [None, None, [np.array([1, 0, 1]), np.array([1, 1])]]
    greedy = agent.greedy_many(states, masks)
    one_by_one = [agent.greedy(s, m) for s, m in zip(states, masks, strict=True)]
    assert [tuple(row) for row in greedy] == one_by_one
    drawn = agent.act_many(states, masks, [0, 1, 2])
    assert drawn == [twin.act(s, m) for s, m in zip(states, masks, strict=True)]
    for copy, (state, joint) in enumerate(zip(states, drawn, strict=True)):
        agent.observe(state, joint, float(copy), copy=copy)
    agent.act_many([1, 2], [None, None], [2, 0])  # copies 2 and 0 go on
    agent.end_episode(final_state=3, terminated=True, copy=1)
    ring = agent._view
    stored = {
        (int(ring.state[k]), int(ring.next_state[k]), bool(ring.terminal[k]))
        for k in range(agent.stored)
    }
    assert stored == {(5, 1, False), (0, 2, False), (4, 4, True)}  # terminal: no successor
    assert agent.steps == 3 and agent.episode == 1
    from dataclasses import replace

    greedy_only = DeepAgent([3, 2], replace(SMALL, eps_start=0.0), 10, n_states=6, seed=0)
    chosen = greedy_only.act_many(states, masks, [0, 1, 2])  # ε = 0: the greedy actions
    assert chosen == [tuple(row) for row in greedy_only.greedy_many(states, masks)]
