"""The fused CPU step of VDN and QMIX against PyTorch's autograd, the reference: the same
loss, gradients, Adam moments and updated weights to float32 rounding, for every input
kind, with terminal transitions, masks and QMIX's hypernetworks; and a hand-computed
mixer."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from cmarlcd import ConfigError  # noqa: E402
from cmarlcd.learners.deep.config import DeepConfig, takes_fused_step  # noqa: E402
from cmarlcd.learners.deep.fused import mixers as fused_mixers  # noqa: E402
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition  # noqa: E402

#: Every mixer: VDN's sum, QMIX's network, and none (deep IQL; hysteretic DQN, its
#: negative TD errors weighed by 0.2).
MIXERS = ["vdn", "qmix", "independent", "hysteretic"]
COUNTS = [3, 4, 2]  # unequal action counts: padded actions are masked
SEEDS, BATCH = 2, 11

#: (name, integer states, features of each agent's own observation, masks in the batch,
#: per-state masks): every way a batch reaches the step.
INPUTS = {
    "features, masks in the batch": (False, None, True, False),
    "features, every action legal": (False, None, False, False),
    "own observations": (False, 3, True, False),
    "integer states": (True, None, False, False),
    "integer states, per-state masks": (True, None, False, True),
    "integer states, masks in the batch": (True, None, True, False),
}


def pair(
    mixer: str, inputs: str, **settings
) -> tuple[ValueDecomposition, ValueDecomposition, callable]:
    """The same model twice, autograd's and the fused step's (same seeds, so the same
    weights), with target networks moved away from the online ones, and a maker of
    random batches of the input kind; ``settings``: more of the :class:`DeepConfig`."""
    index, own, batch_masks, state_masks = INPUTS[inputs]
    in_dim = 6 if index else (4 + len(COUNTS) * own if own else 5)
    config = DeepConfig(
        mixer=mixer, hidden=7, mixer_hidden=5, batch_size=BATCH, gamma=0.8, **settings
    )
    sequences = [np.random.SeedSequence(k) for k in range(SEEDS)]
    models = []
    for step in ("autograd", "fused"):
        model = ValueDecomposition(
            COUNTS, in_dim, DeepConfig(**{**config.__dict__, "step": step}), sequences, own_dim=own
        )
        noise = torch.Generator().manual_seed(5)
        with torch.no_grad():
            for p in [*model.target_agents.parameters(), *model.target_mixer.parameters()]:
                p.add_(0.3 * torch.randn(p.shape, generator=noise))
        models.append(model)
    rng = np.random.default_rng(7)
    n, width = len(COUNTS), max(COUNTS)
    if state_masks:
        legal = torch.as_tensor(rng.random((in_dim, n, width)) < 0.6)
        legal[..., 0] = True
        for model in models:
            model.set_state_legal(legal)

    def batch() -> dict:
        size = (SEEDS, BATCH)
        if index:
            state = torch.as_tensor(rng.integers(0, in_dim, (2, *size)))
        else:
            state = torch.as_tensor(rng.normal(size=(2, *size, in_dim)).astype(np.float32))
        actions = np.stack([rng.integers(0, c, size) for c in COUNTS], axis=-1)
        out = {
            "state": state[0],
            "next_state": state[1],
            "actions": torch.as_tensor(actions),
            "reward": torch.as_tensor(rng.normal(size=size).astype(np.float32)),
            "terminal": torch.as_tensor(rng.random(size) < 0.3),
        }
        if batch_masks:
            legal = rng.random((*size, n, width)) < 0.6
            legal[..., 0] = True
            out["next_legal"] = torch.as_tensor(legal)
        return out

    return models[0], models[1], batch


def parameters(model: ValueDecomposition) -> list[torch.Tensor]:
    return [*model.agents.parameters(), *model.mixer.parameters()]


@pytest.mark.parametrize("double_q", [False, True])
@pytest.mark.parametrize("inputs", list(INPUTS))
@pytest.mark.parametrize("mixer", MIXERS)
def test_fused_gradients_equal_autograd(mixer: str, inputs: str, double_q: bool) -> None:
    """One step from the same weights on the same batch: the same loss and, parameter by
    parameter, the same gradient to float32 rounding (relative to its largest entry);
    with double Q too (the online networks choose the next actions, the targets value
    them)."""
    auto, fused, batch = pair(mixer, inputs, double_q=double_q)
    assert len(parameters(auto)) == (14 if mixer == "qmix" else 4)
    assert_one_step_equal(auto, fused, batch())


def assert_one_step_equal(auto: ValueDecomposition, fused: ValueDecomposition, sample) -> None:
    """One step of each from the same weights on ``sample``: the same loss and, parameter
    by parameter (the fused step's gradients in the module's order), the same gradient to
    float32 rounding (relative to its largest entry)."""
    assert sample["terminal"].any()
    auto.optimizer.zero_grad()
    loss = auto.td_loss(sample)
    loss.backward()
    assert fused.td_step(sample) == pytest.approx(float(loss.detach()) / SEEDS, rel=1e-5)
    grads = fused.fused.flat[1]
    assert len(grads) == len(parameters(auto))
    for p, grad in zip(parameters(auto), grads, strict=True):
        scale = float(p.grad.abs().max())
        assert scale > 0
        np.testing.assert_allclose(grad.reshape(p.shape), p.grad.numpy(), rtol=0, atol=1e-5 * scale)


#: Agent networks of more than one hidden layer, per agent and shared (the fused step takes
#: them on feature states).
DEEPER = {
    "2 layers": {"hidden_layers": 2},
    "3 layers, shared": {"hidden_layers": 3, "share": True},
    "shared": {"share": True},
    "2 layers, shared, two-layer hypernetworks": {
        "hidden_layers": 2,
        "share": True,
        "hypernet_layers": 2,
        "hypernet_hidden": 6,
    },
}
FEATURES = ["features, masks in the batch", "features, every action legal", "own observations"]


#: Cases of the slow set only: each compiles kernels of its own (three layers) for
#: minutes of a fresh checkout's CI; two layers exercise the middle layers in the default set.
SLOW_NETWORKS = {"3 layers, shared"}


@pytest.mark.parametrize(
    "networks",
    [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_NETWORKS else n for n in DEEPER],
)
@pytest.mark.parametrize("inputs", FEATURES)
@pytest.mark.parametrize("mixer", MIXERS)
def test_fused_gradients_equal_autograd_through_middle_layers(
    mixer: str, inputs: str, networks: str
) -> None:
    """As above, for deeper and shared agent networks, with double Q: every middle
    layer's weights and biases get autograd's gradient (a shared network's summed over
    its agents)."""
    settings = dict(DEEPER[networks])
    if mixer != "qmix":  # hypernetworks are QMIX's
        settings.pop("hypernet_layers", None), settings.pop("hypernet_hidden", None)
    auto, fused, batch = pair(mixer, inputs, double_q=True, **settings)
    layers = settings.get("hidden_layers", 1)
    assert len([*auto.agents.parameters()]) == 2 * layers + 2
    assert_one_step_equal(auto, fused, batch())


def test_the_fused_step_takes_one_hidden_layer_on_integer_states() -> None:
    """Integer states read the first layers as tables; the fused step has no middle layer
    nor two-layer hypernetwork there, and says so in one line (autograd's step takes
    them)."""
    _, fused, batch = pair("vdn", "integer states", hidden_layers=2)
    with pytest.raises(ConfigError, match="hidden_layers: the fused step takes 2 hidden"):
        fused.td_step(batch())
    _, fused, batch = pair("qmix", "integer states", hypernet_layers=2)
    with pytest.raises(ConfigError, match="hypernet_layers: the fused step takes two-layer"):
        fused.td_step(batch())


#: EPyMARL's additions (double Q, each seed's gradient norm clipped; a clip this small
#: binds on every step) beside the paper's settings.
EXTRAS = {"paper": {}, "double Q, clipped": {"double_q": True, "grad_clip": 0.05}}


@pytest.mark.parametrize("extras", list(EXTRAS))
@pytest.mark.parametrize(
    "inputs",
    [
        "features, masks in the batch",
        "integer states",
        "integer states, per-state masks",
        "features, 2 layers, shared",
    ],
)
@pytest.mark.parametrize("mixer", MIXERS)
def test_fused_adam_and_weights_follow_autograd_over_steps(
    mixer: str, inputs: str, extras: str
) -> None:
    """Five steps with a target copy and new per-state masks between: Adam's moments and
    the weights stay equal to PyTorch's fused Adam's to float32 rounding (the moments
    check the update's scale, which Adam's first step alone, ±lr, does not); the target
    values both keep between steps are renewed when the targets or the masks change (or,
    with double Q, at every step, as the online networks move)."""
    networks = {}
    if inputs == "features, 2 layers, shared":  # the middle layers' Adam, from spread copies
        inputs, networks = "features, masks in the batch", {"hidden_layers": 2, "share": True}
        if mixer == "qmix":
            networks |= {"hypernet_layers": 2, "hypernet_hidden": 6}
    auto, fused, batch = pair(mixer, inputs, **EXTRAS[extras], **networks)
    for step in range(5):
        sample = batch()
        assert auto.td_step(sample) == pytest.approx(fused.td_step(sample), rel=1e-4)
        if step == 1:
            auto.sync_target(), fused.sync_target()
        if step == 3 and auto.state_legal is not None:
            legal = auto.state_legal.clone()
            legal[..., 1:] = ~legal[..., 1:]  # other masks, action 0 still legal
            auto.set_state_legal(legal), fused.set_state_legal(legal.clone())
    first, second = fused.fused.flat[2], fused.fused.flat[3]
    for k, p in enumerate(parameters(auto)):
        state = auto.optimizer.state[p]
        for ours, theirs in ((first[k], state["exp_avg"]), (second[k], state["exp_avg_sq"])):
            theirs = theirs.numpy().ravel()
            scale = float(np.abs(theirs).max())
            np.testing.assert_allclose(ours, theirs, rtol=1e-3, atol=1e-4 * scale)
    for a, b in zip(parameters(auto), parameters(fused), strict=True):
        np.testing.assert_allclose(b.detach().numpy(), a.detach().numpy(), atol=2e-6)


#: A float32 below the smallest normal one (1.18e-38): a subnormal.
SUBNORMAL = np.float32(1.0e-39)


def subnormal(array: np.ndarray) -> np.ndarray:
    return (array != 0) & (np.abs(array) < np.finfo(np.float32).tiny)


@pytest.mark.parametrize("learner", ["vdn", "qmix", "deep-cmarl-cd"])
def test_fused_step_leaves_no_subnormal_moment(learner: str) -> None:
    """A first moment that has decayed into the subnormals (a parameter the batches have
    missed for a while) is zero after the next step that gives it no gradient, not 0.9 of
    itself (still subnormal, where the CPU's slow path made the DSN's step three times
    slower); parameters that get a gradient are stepped as before, and the others stay
    where they were."""
    if learner == "deep-cmarl-cd":
        _, model, batch = degree_pair(True, "estimate")
    else:
        _, model, batch = pair(learner, "integer states")
    first, grads = model.fused.flat[2], model.fused.flat[1]
    for moment in first:
        moment[:] = SUBNORMAL
    before = [weight.copy() for weight in model.fused.flat[0]]
    model.learn(batch())
    missed = [g == 0 for g in grads]
    assert any(m.any() for m in missed) and not all(m.all() for m in missed)
    for moment, still, weight, old in zip(first, missed, model.fused.flat[0], before, strict=True):
        assert not subnormal(moment).any()
        assert (moment[still] == 0).all()
        assert (moment[~still] != 0).all()
        np.testing.assert_array_equal(weight[still], old[still])


def test_fused_step_leaves_the_threads_float_mode_as_it_found_it() -> None:
    """The flush holds during the step only: a thread that did not flush subnormals does
    not after it, and one that did still does."""
    from cmarlcd.learners.deep.fused.step import flushing_subnormals

    _, fused, batch = pair("vdn", "integer states")
    if not torch.set_flush_denormal(True):
        pytest.skip("this CPU has no flush-to-zero mode")
    try:
        for mode in (False, True, False):
            torch.set_flush_denormal(mode)
            assert flushing_subnormals() is mode
            fused.learn(batch())
            assert flushing_subnormals() is mode
    finally:
        torch.set_flush_denormal(False)


def test_fused_and_autograd_illegal_actions_never_bootstrap() -> None:
    """A next state whose best value is illegal: the fused step's target, like
    autograd's, takes the best legal one (the losses agree only if both mask it)."""
    auto, fused, batch = pair("vdn", "features, masks in the batch")
    sample = batch()
    sample["next_legal"][..., 1:] = False  # only action 0 is legal anywhere
    assert fused.td_step(sample) == pytest.approx(auto.td_step(sample), rel=1e-5)


def test_fused_qmix_mixes_a_hand_chosen_input() -> None:
    """The mixer of the QMIX test in test_value_decomposition, in the fused kernel: two
    agents, q = (1, -2), |W1| = [[1, 2], [0.5, 1]], b1 = [0.5, -1], |w2| = [3, 2]:
    1.5 + 2 (e^-1 - 1) plus V(0) = 2.25, V(1) = 2.75, for one-hot and dense states."""
    f32 = np.float32
    w1 = [1.0, -2.0, 0.5, 1.0]
    tables = {
        "hw1": [w1, w1],
        "hb1": [[0.5, -1.0], [0.5, -1.0]],
        "hw2": [[-3.0, 2.0], [-3.0, 2.0]],
        "v1": [[1.0, -1.0], [0.0, 0.5]],
    }
    mixer = []
    for rows in tables.values():
        mixer += [np.array([rows], f32), np.zeros((1, len(rows[0])), f32)]
    mixer += [np.array([[[2.0], [5.0]]], f32), np.array([[0.25]], f32)]
    mixer += [np.zeros((1, 0, 0), f32), np.zeros((1, 0), f32)] * 2  # one-layer hypernetworks
    c = np.array([[1.0, 1.0], [-2.0, -2.0]], f32)  # (agent, transition)
    mixed = 1.5 + 2 * (math.exp(-1) - 1)
    shapes = [(4, 2), (2, 2), (2, 2), (2, 2), (2, 2), (0, 2), (0, 2), (0, 2)]
    scratch = tuple(np.zeros(shape, f32) for shape in shapes)
    work = fused_mixers.state_scratch(2, 2, 2, 2)
    for index in (True, False):
        q_tot = np.zeros(2, f32)
        states = np.array([0, 1])
        one_hot = np.eye(2, dtype=f32)  # (feature, transition): states 0 and 1
        fused_mixers.mix(True, tuple(mixer), 0, c, one_hot, states, index, scratch, work, q_tot)
        np.testing.assert_allclose(q_tot, [mixed + 2.25, mixed + 2.75], rtol=1e-6)


def test_fused_step_runs_on_the_cpu_only() -> None:
    config = DeepConfig(step="fused")
    model = ValueDecomposition([2], 3, config, [np.random.SeedSequence(0)])
    model.device = torch.device("meta")  # stands for a card: the check reads the device
    from cmarlcd.learners.deep.fused.step import FusedStep

    with pytest.raises(ConfigError, match="CPU"):
        FusedStep(model)


# ------------------------------------------------------------ deep CMARL-CD


def degree_states(rng: np.random.Generator, index: bool, in_dim: int) -> torch.Tensor:
    """A batch's states for deep CMARL-CD's models: (SEEDS, BATCH) integer states below
    ``in_dim``, or (SEEDS, BATCH, in_dim) normal features."""
    size = (SEEDS, BATCH)
    if index:
        return torch.as_tensor(rng.integers(0, in_dim, size))
    return torch.as_tensor(rng.normal(size=(*size, in_dim)).astype(np.float32))


def degree_pair(index: bool, unseen: str, own_dim: int | None = None):
    """Deep CMARL-CD's model twice (autograd's and the fused step's) and a maker of keyed
    batches: kept states, the memory's degrees there and its records; with ``own_dim``
    each agent's degree network reads its own observation, the last features."""
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_model import DegreeModel

    in_dim = 6 if index else 5 + len(COUNTS) * (own_dim or 0)
    sequences = [np.random.SeedSequence(k) for k in range(SEEDS)]
    models = [
        DegreeModel(
            COUNTS,
            in_dim,
            DeepCMARLCDConfig(
                hidden=7, record_hidden=5, batch_size=BATCH, unseen_record=unseen, step=step
            ),
            sequences,
            own_dim=own_dim,
        )
        for step in ("autograd", "fused")
    ]
    rng = np.random.default_rng(3)

    def batch() -> dict:
        size = (SEEDS, BATCH)
        state = degree_states(rng, index, in_dim)
        target = rng.uniform(0.5, 3.0, (*size, len(COUNTS), max(COUNTS))).astype(np.float32)
        record = rng.normal(5.0, 3.0, size).astype(np.float32)
        return {
            "state": state,
            "target": torch.as_tensor(target),
            "record": torch.as_tensor(record),
        }

    return models[0], models[1], batch


def assert_degree_steps_agree(auto, fused, batch, pairs) -> None:
    """After one step of each (autograd's gradients left in ``.grad``): the fused step's
    gradients ``pairs`` (autograd's parameter, the fused gradient) equal to float32
    rounding, then three more steps of each giving the same losses and weights."""
    for p, grad in pairs:
        scale = float(p.grad.abs().max())
        assert scale > 0
        np.testing.assert_allclose(grad, p.grad.numpy(), rtol=0, atol=1e-5 * scale)
    auto.optimizer.step()
    for _ in range(3):
        sample = batch()
        assert auto.learn(sample) == pytest.approx(fused.learn(sample), rel=1e-4)
    for a, b in zip(auto.parameters(), fused.parameters(), strict=True):
        np.testing.assert_allclose(b.detach().numpy(), a.detach().numpy(), atol=1e-4)


@pytest.mark.parametrize("unseen", ["estimate", "first-visit"])
@pytest.mark.parametrize(
    ("index", "own_dim"),
    [(False, None), (True, None), (False, 2)],
    ids=["features", "integer states", "own observations"],
)
def test_fused_degree_step_equals_autograd(index: bool, own_dim: int | None, unseen: str) -> None:
    """The keyed update: the degree networks regressed onto the memory's degrees over each
    agent's real actions and (``estimate``) the record network onto the records (each
    agent's degree network on its own observation, the record network on the whole input,
    with ``own_dim``). One step: the same loss and gradients; three more: the same
    weights, with each network's own learning rate; without an estimate the record
    network is never stepped."""
    auto, fused, batch = degree_pair(index, unseen, own_dim)
    if own_dim:
        assert fused.agents.first.weight.shape[1] == own_dim
    sample = batch()
    auto.optimizer.zero_grad()
    loss = auto.loss(sample)
    loss.backward()
    assert fused.learn(sample) == pytest.approx(float(loss.detach()) / SEEDS, rel=1e-5)
    pairs = list(zip(auto.agents.parameters(), fused.fused.agent_grads, strict=True))
    if unseen == "estimate":
        pairs += list(zip(auto.record.parameters(), fused.fused.record_grads, strict=True))
    assert_degree_steps_agree(auto, fused, batch, pairs)
    if unseen == "first-visit":
        untouched = [
            torch.equal(a, b)
            for a, b in zip(auto.record.parameters(), fused.record.parameters(), strict=True)
        ]
        assert all(untouched)


#: The shares' settings (``update="critic"``, ``critic_form="degrees"``).
SHARES = {"update": "critic", "critic_form": "degrees", "critic_bootstrap": "greedy"}

#: (integer states, features of each agent's own observation, one network shared, hidden
#: layers): the model classes the shares' fused step takes.
SHARES_MODELS = {
    "features": (False, None, False, 1),
    "integer states": (True, None, False, 1),
    "own observations": (False, 2, False, 1),
    "own observations, shared": (False, 2, True, 1),
    "features, two layers": (False, None, False, 2),
    "own observations, shared, three layers": (False, 2, True, 3),
}


def shares_pair(model: str, expectile: float):
    """The shares' model twice (autograd's and the fused step's) and a maker of replay
    batches: states, taken joint actions and stored returns about the summed shares, so
    that some fall below their estimate and some above."""
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_model import DegreeModel

    index, own_dim, share, layers = SHARES_MODELS[model]
    in_dim = 6 if index else 5 + len(COUNTS) * (own_dim or 0)
    sequences = [np.random.SeedSequence(k) for k in range(SEEDS)]
    settings = {"hidden": 7, "record_hidden": 5, "batch_size": BATCH, "expectile": expectile}
    settings |= {"share": share, "hidden_layers": layers, **SHARES}
    models = [
        DegreeModel(
            COUNTS, in_dim, DeepCMARLCDConfig(step=step, **settings), sequences, own_dim=own_dim
        )
        for step in ("autograd", "fused")
    ]
    rng = np.random.default_rng(5)

    def batch() -> dict:
        size = (SEEDS, BATCH)
        state = degree_states(rng, index, in_dim)
        actions = np.stack([rng.integers(0, k, size) for k in COUNTS], axis=-1)
        returns = rng.normal(0.0, 2.0, size).astype(np.float32)
        actions, returns = torch.as_tensor(actions), torch.as_tensor(returns)
        return {"state": state, "actions": actions, "reward": returns}

    return models[0], models[1], batch


@pytest.mark.parametrize("expectile", [0.5, 0.9])
@pytest.mark.parametrize("model", list(SHARES_MODELS))
def test_fused_shares_step_equals_autograd(model: str, expectile: float) -> None:
    """The shares: the degrees summed at each visit's taken joint action, fitted to its
    stored return by the τ-expectile loss, through every model class (a network per
    agent or one shared, one hidden layer or more, each agent on its own observation or
    on the whole input, integer states). One step: the same loss and gradients; three
    more: the same weights; the record network, which the shares do not read, never
    stepped by either."""
    auto, fused, batch = shares_pair(model, expectile)
    sample = batch()
    auto.optimizer.zero_grad()
    loss = auto.loss(sample)
    loss.backward()
    assert fused.learn(sample) == pytest.approx(float(loss.detach()) / SEEDS, rel=1e-5)
    step = fused.fused
    grads = step.shared_grads if step.share else step.agent_grads
    from cmarlcd.learners.deep.fused.step import _in_order

    pairs = list(zip(auto.agents.parameters(), _in_order(grads), strict=True))
    assert_degree_steps_agree(auto, fused, batch, pairs)
    for net in (auto, fused):
        assert all(
            torch.equal(p, q)
            for p, q in zip(net.record.parameters(), net.target_record.parameters(), strict=True)
        )


def test_fused_shares_step_takes_one_hidden_layer_on_integer_states() -> None:
    """Integer states read the first layer as a table; with a middle layer the fused step
    refuses them in one line (autograd's step takes them)."""
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_model import DegreeModel

    config = DeepCMARLCDConfig(hidden=4, hidden_layers=2, step="fused", **SHARES)
    model = DegreeModel(COUNTS, 5, config, [np.random.SeedSequence(0)])
    sample = {
        "state": torch.zeros((1, 3), dtype=torch.int64),
        "actions": torch.zeros((1, 3, len(COUNTS)), dtype=torch.int64),
        "reward": torch.zeros((1, 3)),
    }
    with pytest.raises(ConfigError, match="hidden_layers: the fused step takes 2 hidden"):
        model.learn(sample)


@pytest.mark.parametrize(
    "settings",
    [
        {"update": "replayed"},
        {"share": True},
        {"step": "manual"},
        {"update": "critic", "critic_form": "joint"},
        {"update": "imitation"},
    ],
)
def test_fused_degree_step_is_refused_where_it_does_not_apply(settings: dict) -> None:
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig

    fused = {"step": "fused"} | settings
    with pytest.raises(ConfigError) as info:
        DeepCMARLCDConfig(**fused)
    assert info.value.parameter == "step"


@pytest.mark.parametrize(
    ("settings", "fused"),
    [
        ({}, True),
        ({"update": "replayed"}, False),
        ({"share": True}, False),
        (SHARES, False),
        (SHARES | {"share": True, "hidden_layers": 2}, False),
    ],
)
def test_deep_cmarl_cd_at_step_auto_takes_the_fused_step_where_it_covers(
    settings: dict, fused: bool
) -> None:
    """``step="auto"``: the fused step for the keyed update with a network per agent,
    autograd's for the settings the fused kernels do not cover (no error) and for the
    shares, which ``step="fused"`` takes but no study has compared run by run yet."""
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
    from cmarlcd.learners.deep.degree_model import DegreeModel

    config = DeepCMARLCDConfig(hidden=4, step="auto", **settings)
    model = DegreeModel(COUNTS, 5, config, [np.random.SeedSequence(0)])
    assert (model.fused is not None) is fused


def test_vdn_and_qmix_at_step_auto_take_the_fused_step_on_the_cpu_only() -> None:
    """``step="auto"``: fused on the CPU; on another device autograd's, where an explicit
    ``step="fused"`` is refused."""
    for mixer in ("vdn", "qmix"):
        config = DeepConfig(mixer=mixer, hidden=4, mixer_hidden=3, step="auto")
        assert ValueDecomposition(COUNTS, 5, config, [np.random.SeedSequence(0)]).fused
    assert takes_fused_step("auto", torch.device("cpu"))
    assert not takes_fused_step("auto", torch.device("meta"))  # stands for a card
    assert not takes_fused_step("auto", torch.device("cpu"), covered=False)
    assert not takes_fused_step("autograd", torch.device("cpu"))
    assert takes_fused_step("fused", torch.device("meta"))  # and FusedStep refuses it


def test_deep_runs_stored_before_the_step_setting_read_as_autograd() -> None:
    """A stored identity without ``step`` is a run of 0.5.x, which took autograd's step;
    the other steps carry theirs, so their runs are others, whatever the default."""
    from dataclasses import replace

    from cmarlcd import registry
    from cmarlcd.runs import identity

    for name in ("vdn", "qmix", "deep-cmarl-cd"):
        default = registry.LEARNERS[name]
        stored = {k: v for k, v in identity(default).items() if k != "step"}
        assert registry.learner_config(name, stored).step == "autograd"
        assert "step" not in identity(replace(default, step="autograd"))
        for step in ("auto", "fused"):
            assert identity(replace(default, step=step))["step"] == step


def test_the_kernels_expm1_is_correctly_rounded() -> None:
    """QMIX's ELU in the kernels: exp(p) - 1 for p <= 0 within half a float32 ulp (plus
    the float64 series' own error) of NumPy's float64 expm1, from -10⁻⁴⁰ to -100, with
    -1 below -87 and 0 at 0; positive inputs pass through."""
    negative = -np.logspace(-40, 2, 20_001).astype(np.float32)
    inputs = np.concatenate([negative, np.float32([0.0, -0.0, -87.0, -88.0, -1e30, 1.5])])
    exact = np.where(inputs > 0, inputs, np.expm1(inputs.astype(np.float64)))
    got = fused_mixers.elu_of(inputs)
    ulp = np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)
    assert np.max(np.abs(got - exact) / ulp) <= 0.5 + 1e-3
    assert got[-3] == -1.0 and got[-6] == 0.0 and got[-1] == np.float32(1.5)


def test_stale_kernel_caches_go_when_any_fused_source_changes(tmp_path) -> None:
    """Numba checks a cache against its own file only; a change to any fused module
    must drop every fused cache (a caller would otherwise keep an old callee)."""
    from cmarlcd.learners.deep.fused.layers import drop_stale_caches

    (tmp_path / "fused_a.py").write_text("x = 1\n")
    (tmp_path / "fused_b.py").write_text("y = 1\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()
    compiled = cache / "fused_a.td_step-1.py311.nbi"
    compiled.write_bytes(b"old")
    assert drop_stale_caches(tmp_path) and not compiled.exists()  # no stamp yet
    compiled.write_bytes(b"new")
    assert not drop_stale_caches(tmp_path) and compiled.exists()  # nothing changed
    (tmp_path / "fused_b.py").write_text("y = 2\n")  # the callee's module, not a's
    assert drop_stale_caches(tmp_path) and not compiled.exists()
