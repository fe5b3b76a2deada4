"""Deep CMARL-CD: Algorithm 2's updates as regression targets (record, tie, neither),
the record network's expectile, the stored returns, and a one-state game solved."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd import ConfigError
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig

torch = pytest.importorskip("torch")

from cmarlcd.learners.deep.degree_model import DegreeModel  # noqa: E402


def model(config: DeepCMARLCDConfig | None = None, counts=(3,), in_dim: int = 1) -> DegreeModel:
    seeds = [np.random.SeedSequence(0)]
    return DegreeModel(counts, in_dim, config or DeepCMARLCDConfig(), seeds)


def test_a_record_resets_a_tie_reinforces_and_a_lower_return_leaves_the_degrees() -> None:
    """c_init 1.5, δ 0.05, δ_reset 0.5, c in [0.5, 3] (the defaults); margin and tolerance
    0.5."""
    degrees = torch.tensor([[2.0, 1.0, 2.98]]).expand(4, 3)[None, :, None, :]  # (1, 4, 1, 3)
    actions = torch.tensor([[[2], [2], [0], [1]]])
    returns = torch.tensor([[10.0, 5.3, 5.5, 4.0]])
    record = torch.full((1, 4), 5.0)
    config = DeepCMARLCDConfig(margin=0.5, tolerance=0.5)
    target, updated = model(config).targets(degrees, actions, returns, record)
    assert updated.tolist() == [[True, True, True, False]]
    expected = [
        [1.0, 1.0, 2.0],  # 10 > 5 + 0.5: reset to 1.5, then ±0.5
        [1.95, 0.95, 3.0],  # |5.3 - 5| <= 0.5: ±0.05 (3.03 clipped to c_max)
        [2.05, 0.95, 2.93],  # 5.5 is not above 5 + 0.5: a tie
    ]
    assert torch.allclose(target[0, :3, 0], torch.tensor(expected))


def test_degrees_outside_the_bounds_are_read_clipped() -> None:
    degrees = torch.tensor([[[[7.0, -2.0]]]])
    target, _ = model(counts=(2,)).targets(
        degrees, torch.tensor([[[1]]]), torch.tensor([[5.0]]), torch.tensor([[5.0]])
    )
    assert target[0, 0, 0].tolist() == pytest.approx([2.95, 0.55])  # from (3.0, 0.5)


def test_the_record_network_fits_the_expectile_of_the_returns() -> None:
    """Returns 0 and 10 equally often: the τ-expectile v solves τ(10 - v) = (1 - τ) v,
    so v = 10 τ (9 at τ = 0.9)."""
    net = model(DeepCMARLCDConfig(update="replayed", expectile=0.9, lr=0.02))
    batch = {
        "state": torch.zeros((1, 2), dtype=torch.int64),
        "actions": torch.zeros((1, 2, 1), dtype=torch.int64),
        "reward": torch.tensor([[0.0, 10.0]]),
    }
    for _ in range(3000):
        net.learn(batch)
    estimate = float(net.record(batch["state"]).detach()[0, 0])
    assert estimate == pytest.approx(9.0, abs=0.05)


def test_shared_degree_network_gives_the_loop_each_agent_s_layers() -> None:
    """The per-agent weights the compiled loop reads compute what the network computes."""
    net = model(DeepCMARLCDConfig(share=True, hidden=5), counts=(2, 3), in_dim=4)
    x = torch.randn(1, 6, 4)
    w1, b1, w2, b2, wm, bm = net.agents.feature_weights()
    assert wm.shape == (2, 0, 5, 5) and bm.shape == (2, 0, 5)  # one hidden layer
    for i in range(2):
        by_hand = torch.relu(x[0] @ w1[i] + b1[i]) @ w2[i] + b2[i]
        assert torch.allclose(net.agents(x)[0, :, i], by_hand, atol=1e-5)
    one_hot = torch.eye(4)[None]
    assert torch.allclose(net.agents(one_hot)[0], net.agents.tables()[0], atol=1e-5)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("expectile", 1.0),
        ("margin", -1.0),
        ("c_init", 9.0),
        ("hidden", 0),
        ("tolerance", np.nan),
        ("update", "bogus"),
        ("unseen_record", "never"),
        ("act_from", "table"),
        ("record", "mean"),
        ("record_step", 0.0),
        ("record_step", 1.5),
        ("ways", 0),
        ("ways", 50_000),
    ],
)
def test_bad_settings_are_rejected(field, value) -> None:
    with pytest.raises(ConfigError) as err:
        DeepCMARLCDConfig(**{field: value})
    assert err.value.parameter == field


def test_acting_from_the_memory_needs_the_keyed_memory() -> None:
    """The first design keeps no degrees per state: there is no memory to act from."""
    with pytest.raises(ConfigError, match="keyed") as err:
        DeepCMARLCDConfig(update="replayed", act_from="memory")
    assert err.value.parameter == "act_from"


def test_the_expectile_record_is_kept_in_the_keyed_memory() -> None:
    """The first design's record is its record network's expectile; the memory's
    expectile record needs the memory."""
    with pytest.raises(ConfigError, match="keyed") as err:
        DeepCMARLCDConfig(update="replayed", record="expectile")
    assert err.value.parameter == "record"


def test_an_episode_is_stored_visit_by_visit_with_its_discounted_returns() -> None:
    """Rewards 1, 2, 4 and γ = 0.5: returns 1 + 0.5·4 = 3, 2 + 0.5·4 = 4, 4 (eq. 1),
    stored from the last visit back."""
    from cmarlcd.learners.deep.replay import new_ring, seed_view
    from cmarlcd.training.deep_kernels import EPISODES, IndexData
    from cmarlcd.training.degree_kernels import index_store

    ring = new_ring(1, 8, 2, 3, 10)
    schedule = np.array(DeepCMARLCDConfig(gamma=0.5).schedule(100), np.float64)
    side = IndexData(
        np.array([3, 3]),
        np.zeros((10, 2, 3), np.float32),
        np.ones((10, 2, 3), np.bool_),
        np.zeros(10, np.bool_),
        np.array([7, 8, 9, 0]),
        np.array([[0, 1], [2, 2], [1, 0]]),
        np.array([1.0, 2.0, 4.0]),
        seed_view(ring, 0),
        np.zeros(4, np.int64),
        schedule,
        np.zeros((2, 3)),
    )
    index_store(side, 3)
    assert ring.size[0] == 3 and side.counters[EPISODES] == 1
    assert ring.reward[0, :3].tolist() == [4.0, 4.0, 3.0]
    assert ring.state[0, :3].tolist() == [9, 8, 7]
    assert ring.actions[0, :3].tolist() == [[1, 0], [2, 2], [0, 1]]


def test_a_one_state_game_is_solved() -> None:
    """The climbing game as a one-step stochastic game: every seed's greedy joint action
    is the optimum (0, 0), 11, which the other joint actions' 7, 6, 5 surround."""
    from cmarlcd.games.matrix import climbing_game
    from cmarlcd.training.deep import DeepBatch

    spec = climbing_game().spec()
    config = DeepCMARLCDConfig(buffer_size=500, batch_size=50, train_every=10, target_every=50)
    final = {}
    batch = DeepBatch(spec, config, [np.random.SeedSequence(k) for k in range(5)], 3_000)
    batch.train([], lambda k, budget, policy: final.__setitem__(k, policy.table[0].tolist()))
    assert list(final.values()) == [[0, 0]] * 5


def test_the_spread_tolerance_is_rejected_where_no_estimate_is_read() -> None:
    with pytest.raises(ConfigError, match="unseen_tolerance"):
        DeepCMARLCDConfig(unseen_tolerance=0.1, unseen_record="first-visit")
    with pytest.raises(ConfigError, match="unseen_tolerance"):
        DeepCMARLCDConfig(unseen_tolerance=0.1, update="imitation")
    with pytest.raises(ConfigError, match="unseen_tolerance"):
        DeepCMARLCDConfig(unseen_tolerance=-1.0)
    with pytest.raises(ConfigError, match="unseen_spread"):
        DeepCMARLCDConfig(unseen_tolerance=0.1, unseen_spread="iqr")
    assert DeepCMARLCDConfig(unseen_tolerance=0.1, unseen_spread="range").unseen_tolerance == 0.1
