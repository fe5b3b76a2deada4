"""More hidden layers (``hidden_layers``) for VDN, QMIX, deep IQL and hysteretic DQN:
EPyMARL's feed-forward agent has two. The networks, the compiled loop's forward pass,
the kept policies and the settings."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd.errors import ConfigError  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition  # noqa: E402
from cmarlcd.training.deep_kernels import (  # noqa: E402
    Weights,
    greedy_agent_at,
    hidden_layer_at,
    hidden_scratch,
)

#: Inputs laid out as [s (4), o_1 (3), o_2 (3)], as in test_value_decomposition.
STATE, OWN, AGENTS, HIDDEN = 4, 3, 2, 5


def model(share: bool, layers: int = 2, mixer: str = "vdn") -> ValueDecomposition:
    config = DeepConfig(
        mixer=mixer, hidden=HIDDEN, share=share, hidden_layers=layers, step="autograd"
    )
    seeds = [np.random.SeedSequence(0)]
    return ValueDecomposition([3, 3], STATE + AGENTS * OWN, config, seeds, own_dim=OWN)


def relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0)


@pytest.mark.parametrize("share", [False, True])
def test_two_hidden_layers_by_hand_and_as_the_loop_reads_them(share: bool) -> None:
    """Agent i's values are W2 ReLU(Wm ReLU(W1 x_i + b1) + bm) + b2, computed here from
    the network's own layers (x_i: its observation, with its one-hot index where the
    network is shared); the per-agent layers the compiled loop reads give the same."""
    net = model(share).agents
    state = torch.randn(1, 6, STATE + AGENTS * OWN, generator=torch.Generator().manual_seed(1))
    q = net(state).detach().numpy()[0]  # (6, n, A)
    w1, b1 = (t.detach().numpy()[0] for t in (net.first.weight, net.first.bias))
    wm, bm = (t.detach().numpy()[0] for t in (net.middle[0].weight, net.middle[0].bias))
    w2, b2 = (t.detach().numpy()[0] for t in (net.second.weight, net.second.bias))
    loop = [t.detach().numpy() for t in net.feature_weights()]
    assert loop[4].shape == (AGENTS, 1, HIDDEN, HIDDEN) and loop[5].shape == (AGENTS, 1, HIDDEN)
    x = state.numpy()[0]
    for i in range(AGENTS):
        own = x[:, STATE + i * OWN : STATE + (i + 1) * OWN]
        if share:
            index = np.zeros((len(own), AGENTS), np.float32)
            index[:, i] = 1.0
            first = relu(np.hstack([own, index]) @ w1 + b1)
            expected = relu(first @ wm + bm) @ w2 + b2
        else:  # per-agent networks: agent i's rows of every layer
            w1, b1 = net.first.weight.detach().numpy()[i], net.first.bias.detach().numpy()[i]
            wm = net.middle[0].weight.detach().numpy()[i]
            bm = net.middle[0].bias.detach().numpy()[i]
            w2, b2 = net.second.weight.detach().numpy()[i], net.second.bias.detach().numpy()[i]
            expected = relu(relu(own @ w1 + b1) @ wm + bm) @ w2 + b2
        np.testing.assert_allclose(q[:, i], expected, rtol=1e-5, atol=1e-6)
        by_loop = relu(relu(own @ loop[0][i] + loop[1][i]) @ loop[4][i, 0] + loop[5][i, 0])
        by_loop = by_loop @ loop[2][i] + loop[3][i]
        np.testing.assert_allclose(by_loop, expected, rtol=1e-5, atol=1e-6)


def test_one_hot_states_through_two_layers_are_the_networks_values() -> None:
    """Integer states: the tables (and the loop's copy of them) are the forward pass of
    each one-hot vector."""
    config = DeepConfig(hidden=HIDDEN, hidden_layers=3, step="autograd")
    vd = ValueDecomposition([3, 2], 7, config, [np.random.SeedSequence(1)])
    assert len(vd.agents.middle) == 2
    one_hot = torch.eye(7)[None]
    tables = vd.agents.tables()
    assert torch.allclose(vd.agents(one_hot), tables, atol=1e-6)
    out = np.zeros(tuple(tables.shape), np.float32)
    vd.agents.copy_tables(out)
    np.testing.assert_array_equal(out, tables.detach().numpy())
    states = torch.tensor([[3, 0, 6]])
    assert torch.equal(vd.agents(states)[0], tables[0, [3, 0, 6]])


def test_the_compiled_forward_pass_sums_each_layer_in_float32_and_acts_greedily() -> None:
    """The kernel's hidden layers, each sum rounded to float32 in feature order (as
    NumPy's float32 scalars round them, one unit at a time), and its greedy action the
    legal action of largest value computed by hand."""
    rng = np.random.default_rng(4)
    features, units, width = 6, 4, 3
    shapes = ((2, features, units), (2, units), (2, units, width), (2, width),
              (2, 2, units, units), (2, 2, units))  # fmt: skip
    weights = Weights(*(rng.standard_normal(s).astype(np.float32) for s in shapes))
    x = rng.standard_normal(features + 2).astype(np.float32)
    hidden = hidden_scratch(weights)
    assert hidden.shape == (2 * units,)
    for agent in range(2):
        hidden_layer_at(weights, agent, x, 2, hidden)
        h = np.zeros(units, np.float32)
        for u in range(units):  # the first layer, reading x from feature 2
            z = weights.b1[agent, u]
            for f in range(features):
                z = np.float32(z + np.float32(x[2 + f] * weights.w1[agent, f, u]))
            h[u] = max(z, np.float32(0.0))
        for m in range(2):  # then each middle layer on the last
            nxt = np.zeros(units, np.float32)
            for u in range(units):
                z = weights.bm[agent, m, u]
                for f in range(units):
                    if h[f] != 0.0:
                        z = np.float32(z + np.float32(h[f] * weights.wm[agent, m, f, u]))
                nxt[u] = max(z, np.float32(0.0))
            h = nxt
        np.testing.assert_array_equal(hidden[:units], h)
        values = h.astype(np.float64) @ weights.w2[agent].astype(np.float64) + weights.b2[agent]
        legal = np.array([True, False, True])
        best = int(np.argmax(np.where(legal, values, -np.inf)))
        assert greedy_agent_at(weights, agent, x, 2, legal, width, hidden) == best


def test_the_setting_is_checked_and_keeps_autograds_step() -> None:
    with pytest.raises(ConfigError, match="hidden_layers"):
        DeepConfig(hidden_layers=0)
    assert DeepConfig(hidden_layers=2, step="fused").hidden_layers == 2  # on features
    assert DeepConfig(mixer="qmix").auto_fuses
    assert not DeepConfig(mixer="qmix", hidden_layers=2).auto_fuses
    vd = model(share=False, mixer="qmix")
    assert getattr(vd, "fused", None) is None  # autograd's step under step=auto
    one = model(share=False, layers=1)
    assert [name for name, _ in one.agents.named_parameters()] == [
        "first.weight", "first.bias", "second.weight", "second.bias"
    ]  # fmt: skip


def test_a_two_layer_run_keeps_policies_that_replay_its_store(tmp_path) -> None:
    """End to end: LBF's deep IQL with two hidden layers, shared, and QMIX with two
    hidden layers per agent and two-layer hypernetworks, on their own observations;
    each seed's kept networks (with their middle layer) replay the stored return of its
    last evaluation."""
    store, kept = tmp_path / "s.sqlite", tmp_path / "policies"

    def cli(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "cmarlcd", *args], capture_output=True,
                              text=True, check=False)  # fmt: skip

    done = cli("train", "--game", "foraging:5x5-2p-1f", "--algorithms", "deep-iql,qmix",
               "--steps", "1500", "--runs", "2", "--inputs", "own-observations", "--set",
               "deep-iql.hidden_layers=2,deep-iql.share=true,qmix.hidden_layers=2,"
               "qmix.hypernet_layers=2", "--workers", "1",
               "--no-progress", "--store", str(store), "--figures", str(tmp_path / "f"),
               "--save-policies", str(kept))  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    files = sorted(kept.glob("*.safetensors"))
    assert len(files) == 4
    for path in files:
        doc = json.loads(cli("evaluate", "--policy", str(path), "--store", str(store),
                             "--json").stdout)  # fmt: skip
        assert doc["mean_return"] == doc["stored_return"]
    from cmarlcd.policies.files import load_policy

    arrays = load_policy(files[0]).arrays()
    units = arrays["w1"].shape[2]
    assert arrays["wm"].shape == (AGENTS, 1, units, units)
    assert arrays["bm"].shape == (AGENTS, 1, units)


def test_qmix_with_two_layer_hypernetworks_by_hand_and_monotonic() -> None:
    """QMIX's mixing weights from hypernetworks of two layers (EPyMARL's
    ``hypernet_layers: 2``): Q_tot = Σ_k ELU(Σ_i q_i |W1(s)|_ik + b1(s)_k) |w2(s)|_k + V(s),
    W1(s) = L2(ReLU(L1(s))), computed here from the mixer's layers; one-hot states give
    what their feature vectors give; Q_tot never falls as an agent's value rises."""
    config = DeepConfig(mixer="qmix", hidden=HIDDEN, mixer_hidden=3, hypernet_layers=2,
                        hypernet_hidden=4, step="autograd")  # fmt: skip
    vd = ValueDecomposition([3, 3], 6, config, [np.random.SeedSequence(2)])
    mixer = vd.mixer
    assert mixer.hyper_w1.first.weight.shape == (1, 6, 4)
    assert mixer.hyper_w1.second.weight.shape == (1, 4, AGENTS * 3)
    generator = torch.Generator().manual_seed(0)
    state = torch.randn(1, 5, 6, generator=generator)
    q = torch.randn(1, 5, AGENTS, generator=generator)

    def layer(module, x):
        return x @ module.weight.detach().numpy()[0] + module.bias.detach().numpy()[0]

    s = state.numpy()[0]
    w1 = np.abs(layer(mixer.hyper_w1.second, relu(layer(mixer.hyper_w1.first, s))))
    w2 = np.abs(layer(mixer.hyper_w2.second, relu(layer(mixer.hyper_w2.first, s))))
    b1, value = layer(mixer.hyper_b1, s), layer(mixer.value_2, relu(layer(mixer.value_1, s)))
    pre = np.einsum("ni,nik->nk", q.numpy()[0], w1.reshape(5, AGENTS, 3)) + b1
    elu = np.where(pre > 0, pre, np.expm1(pre))
    expected = (elu * w2).sum(axis=1) + value[:, 0]
    # float32 against float64 arithmetic: a total near 0 after cancelling terms of order 1
    # keeps their absolute rounding, not a relative one
    np.testing.assert_allclose(mixer(q, state).detach().numpy()[0], expected, rtol=1e-5, atol=1e-6)
    one_hot = torch.eye(6)[None, [0, 3, 5]]
    np.testing.assert_allclose(
        mixer(q[:, :3], torch.tensor([[0, 3, 5]])).detach().numpy(),
        mixer(q[:, :3], one_hot).detach().numpy(), rtol=1e-5, atol=1e-6,
    )  # fmt: skip
    q.requires_grad_(True)
    mixer(q, state).sum().backward()
    assert (q.grad >= 0).all()


def test_the_hypernetwork_setting_is_checked() -> None:
    for settings, says in (
        ({"mixer": "qmix", "hypernet_layers": 3}, "must be 1 or 2"),
        ({"mixer": "vdn", "hypernet_layers": 2}, "applies to qmix only"),
        ({"mixer": "qmix", "hypernet_hidden": 0}, "hypernet_hidden"),
    ):
        with pytest.raises(ConfigError, match=says):
            DeepConfig(**settings)
    assert not DeepConfig(mixer="qmix", hypernet_layers=2).auto_fuses
    assert DeepConfig(mixer="qmix", hypernet_layers=2, step="fused").step == "fused"
    assert DeepConfig(mixer="qmix", hypernet_hidden=8).auto_fuses  # read only with 2
