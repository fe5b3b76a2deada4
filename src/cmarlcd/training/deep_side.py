"""VDN or QMIX as one side of a match (:mod:`cmarlcd.training.match`; ``[deep]`` extra).

The side sees its state as the game's feature vector (``game.features``), not as an
index: the battlefield's 802,816 states per side are far too many for one-hot inputs.
Inside the compiled loop it acts ε-greedily (eq. 18, annealed over the match's learning
episodes) with its agent networks' forward pass, compiled here over a copy of their
weights, and appends each turn to its replay buffer. Every ``train_every`` turns the loop
stops, and :meth:`DeepSide.between_calls` takes the gradient step (once
``batch_size`` transitions are stored, then a target copy whenever another
``target_every`` turns have passed) on the model of
:class:`cmarlcd.learners.value_decomposition.ValueDecomposition` and copies the new
weights back for the loop. The networks change only there, so acting with the copy is
acting with the networks.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch

from cmarlcd.compiled import Unbound, kernel, specialise
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep_config import DeepConfig, epsilon_schedule
from cmarlcd.learners.policy import annealed_epsilon, uniform_legal_action
from cmarlcd.learners.value_decomposition import ValueDecomposition
from cmarlcd.training.match import MatchSide, SideKernels

game = Unbound("game")

#: Entries of a deep side's ``counters``: the ring's next row and size, turns observed,
#: episodes finished, and the turns observed when the loop last paused for it.
POSITION, SIZE, TURNS, EPISODES, PAUSED_AT = range(5)


class Weights(NamedTuple):
    """A copy of the agent networks' parameters, agent-major (float32)."""

    w1: np.ndarray
    """(n_agents, n_features, hidden)"""
    b1: np.ndarray
    """(n_agents, hidden)"""
    w2: np.ndarray
    """(n_agents, hidden, width)"""
    b2: np.ndarray
    """(n_agents, width)"""


class Replay(NamedTuple):
    """One side's ring of transitions (features, not state indices)."""

    obs: np.ndarray
    actions: np.ndarray
    reward: np.ndarray
    next_obs: np.ndarray
    next_legal: np.ndarray
    terminal: np.ndarray


class DeepData(NamedTuple):
    """One deep side's arrays, as the side kernels read them."""

    counts: np.ndarray
    weights: Weights
    hidden: np.ndarray
    """Scratch: one agent's hidden layer."""
    obs: np.ndarray
    """The episode so far: each turn's features, (max_steps + 1, n_features) ..."""
    legal: np.ndarray
    """... its legal actions, (max_steps + 1, n_agents, width) ..."""
    joints: np.ndarray
    rewards: np.ndarray
    replay: Replay
    counters: np.ndarray
    schedule: np.ndarray
    """ε schedule (start, end, anneal fraction, after), learning episodes, train_every."""


@kernel
def hidden_layer(weights, agent: int, x, hidden) -> None:
    """``hidden`` := ReLU(x W1 + b1) of agent ``agent``."""
    w1, b1 = weights[0], weights[1]
    for h in range(hidden.shape[0]):
        z = b1[agent, h]
        for f in range(x.shape[0]):
            z += x[f] * w1[agent, f, h]
        hidden[h] = z if z > 0.0 else 0.0


@kernel
def greedy_agent(weights, agent: int, x, legal_row, count: int, hidden) -> int:
    """The agent's legal action of largest Q at ``x`` (lowest index on ties)."""
    hidden_layer(weights, agent, x, hidden)
    w2, b2 = weights[2], weights[3]
    best, best_q = -1, 0.0
    for a in range(count):
        if not legal_row[a]:
            continue
        q = b2[agent, a]
        for h in range(hidden.shape[0]):
            q += hidden[h] * w2[agent, h, a]
        if best < 0 or q > best_q:
            best, best_q = a, q
    return best


@kernel
def deep_fits(side, max_steps: int) -> bool:
    """A deep side's memory does not grow with the states it sees."""
    return True


def deep_enter(side, env, team, offset, legal, length) -> int:
    """Template: turn ``length``'s features and legal actions into the episode record."""
    game.features(env, team, side.obs[length])
    game.legal(env, legal)
    for i in range(side.counts.shape[0]):
        for a in range(legal.shape[1]):
            side.legal[length, i, a] = legal[offset + i, a]
    return length


@kernel
def deep_act(side, key: int, rng, joint) -> None:
    """ε-greedy (eq. 18): each agent independently a uniform legal action with
    probability ε, else its greedy legal action."""
    s = side.schedule
    eps = annealed_epsilon(side.counters[EPISODES] + 1, int(s[4]), s[0], s[1], s[2], s[3])
    x, legal = side.obs[key], side.legal[key]
    for i in range(side.counts.shape[0]):
        count = side.counts[i]
        if rng.random() < eps:
            joint[i] = uniform_legal_action(legal[i], count, rng.random())
        else:
            joint[i] = greedy_agent(side.weights, i, x, legal[i], count, side.hidden)


@kernel
def deep_observe(side, t: int, next_key: int, terminal: bool) -> None:
    """Append turn ``t`` to the ring (the oldest overwritten when full). A terminal
    transition's next state is never bootstrapped from; its masks are set all legal so
    the target's maximum stays finite."""
    replay, c = side.replay, side.counters
    p = c[POSITION]
    for f in range(side.obs.shape[1]):
        replay.obs[p, f] = side.obs[t, f]
        replay.next_obs[p, f] = side.obs[t + 1, f] if not terminal else 0.0
    for i in range(side.counts.shape[0]):
        replay.actions[p, i] = side.joints[t, i]
        for a in range(side.legal.shape[2]):
            replay.next_legal[p, i, a] = side.legal[t + 1, i, a] if not terminal else True
    replay.reward[p] = side.rewards[t]
    replay.terminal[p] = terminal
    c[POSITION] = (p + 1) % replay.obs.shape[0]
    c[SIZE] = min(c[SIZE] + 1, replay.obs.shape[0])
    c[TURNS] += 1


@kernel
def deep_end_episode(side, length: int) -> None:
    side.counters[EPISODES] += 1


@kernel
def deep_pause(side) -> bool:
    """Stop the loop every ``train_every`` turns, for the gradient step."""
    return side.counters[TURNS] - side.counters[PAUSED_AT] >= side.schedule[5]


def deep_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: every agent's greedy legal action at the side's features (``rng`` is not
    drawn from: a network has a greedy action in every state)."""
    x = side.obs[0]
    game.features(env, team, x)
    game.legal(env, legal)
    for i in range(joint.shape[0]):
        joint[i] = greedy_agent(side.weights, i, x, legal[offset + i], side.counts[i], side.hidden)


def deep_kernels(spec: GameSpec) -> SideKernels:
    """The side kernels of a deep learner on ``spec``."""
    bound = {"game": spec.kernels}
    return SideKernels(
        deep_fits,
        specialise(deep_enter, **bound),
        deep_act,
        deep_observe,
        deep_end_episode,
        deep_pause,
        specialise(deep_greedy, **bound),
    )


class DeepGroup:
    """The VDN or QMIX sides of B matches, trained as one stacked model: one seed per
    match, each with its own parameters, replay buffer and streams (the gradient steps
    of the B seeds are taken together, as in :mod:`cmarlcd.training.deep`).

    Each match's side is a :class:`DeepSide` view whose weights are views into the
    stacked copy. Side b's streams come from ``rngs[b]``'s seed sequence: actions from
    ``rngs[b]`` itself, network initialisation and replay sampling from two children
    spawned from it, so a match plays the same whether it is batched or alone.

    Matches of one pairing pause at the same turn counts (every ``train_every`` turns of
    each), so while they all learn, one step of the stacked model is each one's step. A
    side whose match has finished learning keeps (:meth:`DeepSide.freeze`) the weights
    it finished with.
    """

    def __init__(
        self,
        spec: GameSpec,
        teams: Sequence[int],
        config: DeepConfig,
        rngs: Sequence[np.random.Generator],
        learn_episodes: int,
    ) -> None:
        require(
            spec.n_features > 0,
            "game",
            f"{config.display_name} on one side of a match needs a game with state features; "
            f"{spec.name} has none",
        )
        counts = spec.action_counts[list(spec.teams[teams[0]])].copy()
        same = all(np.array_equal(spec.action_counts[list(spec.teams[t])], counts) for t in teams)
        require(same, "teams", "one stacked model needs sides with the same action counts")
        n, width, features = counts.shape[0], int(counts.max()), spec.n_features
        seeds = [rng.bit_generator.seed_seq.spawn(2) for rng in rngs]
        self.config, self.spec = config, spec
        self.model = ValueDecomposition(counts, features, config, [s[0] for s in seeds])
        self.replay_rngs = [np.random.default_rng(s[1]) for s in seeds]
        groups = len(rngs) * n
        self.weights = Weights(
            np.zeros((groups, features, config.hidden), np.float32),
            np.zeros((groups, config.hidden), np.float32),
            np.zeros((groups, config.hidden, width), np.float32),
            np.zeros((groups, width), np.float32),
        )
        kernels = deep_kernels(spec)
        self.views = [DeepSide(self, b, counts, kernels, learn_episodes) for b in range(len(rngs))]
        self._copy_weights()

    def train(self) -> None:
        """The gradient step and target copy due once the learning sides have played
        ``train_every`` more turns (all of them: they pause at the same turn counts)."""
        cfg = self.config
        due = [view for view in self.views if view.due()]
        if not due:
            return
        learning = [view for view in self.views if not view.frozen]
        require(
            all(view.due() for view in learning),
            "matches",
            "the matches of one batch must pause together",
        )
        previous, turns = int(due[0].counters[PAUSED_AT]), int(due[0].counters[TURNS])
        for view in due:
            view.counters[PAUSED_AT] = view.counters[TURNS]
        if min(int(view.counters[SIZE]) for view in due) >= cfg.batch_size:
            self.model.td_step(self.sample())
            self._copy_weights()
        if turns // cfg.target_every > previous // cfg.target_every:
            self.model.sync_target()

    def sample(self) -> dict[str, torch.Tensor]:
        """A replay batch per seed, uniformly with replacement, with its own generator (a
        side with nothing stored yet gets zeros: it is frozen, its step is discarded)."""
        size = self.config.batch_size
        parts = []
        for view, rng in zip(self.views, self.replay_rngs, strict=True):
            stored = int(view.counters[SIZE])
            picks = rng.integers(0, stored, size) if stored else np.zeros(size, np.int64)
            parts.append([array[picks] for array in view.data.replay])
        stacked = [torch.from_numpy(np.stack(column)) for column in zip(*parts, strict=True)]
        names = ("state", "actions", "reward", "next_state", "next_legal", "terminal")
        return dict(zip(names, stacked, strict=True))

    def _copy_weights(self) -> None:
        """The loops' copy of the agent networks := the networks."""
        agents = self.model.agents
        with torch.no_grad():
            np.copyto(self.weights.w1, agents.first.weight.numpy())
            np.copyto(self.weights.b1, agents.first.bias.numpy())
            np.copyto(self.weights.w2, agents.second.weight.numpy())
            np.copyto(self.weights.b2, agents.second.bias.numpy())

    def memory_bytes(self) -> int:
        """Parameters (online and target networks, Adam's two moments)."""
        return 4 * sum(p.numel() * p.element_size() for p in self.model.parameters())


class DeepSide(MatchSide):
    """VDN or QMIX on one side of one match: a view of seed ``index`` of a
    :class:`DeepGroup` (alone, a group of one trains itself between loop calls)."""

    def __init__(
        self,
        group: DeepGroup,
        index: int,
        counts: np.ndarray,
        kernels: SideKernels,
        learn_episodes: int,
    ) -> None:
        config, spec = group.config, group.spec
        n, width, features = counts.shape[0], int(counts.max()), spec.n_features
        steps, size = spec.max_steps, config.buffer_size
        agents = slice(index * n, (index + 1) * n)
        self.group, self.kernels, self.frozen = group, kernels, False
        self.data = DeepData(
            counts,
            Weights(*(array[agents] for array in group.weights)),
            np.zeros(config.hidden),
            np.zeros((steps + 1, features), np.float32),
            np.zeros((steps + 1, n, width), np.bool_),
            np.zeros((steps, n), np.int64),
            np.zeros(steps),
            Replay(
                np.zeros((size, features), np.float32),
                np.zeros((size, n), np.int64),
                np.zeros(size, np.float32),
                np.zeros((size, features), np.float32),
                np.zeros((size, n, width), np.bool_),
                np.zeros(size, np.bool_),
            ),
            np.zeros(5, np.int64),
            np.array([*epsilon_schedule(config), learn_episodes, config.train_every], float),
        )

    @classmethod
    def alone(
        cls,
        spec: GameSpec,
        team: int,
        config: DeepConfig,
        rng: np.random.Generator,
        learn_episodes: int,
    ) -> DeepSide:
        """The deep side of a match played on its own."""
        return DeepGroup(spec, [team], config, [rng], learn_episodes).views[0]

    @property
    def counters(self) -> np.ndarray:
        return self.data.counters

    @property
    def model(self) -> ValueDecomposition:
        return self.group.model

    @property
    def config(self) -> DeepConfig:
        return self.group.config

    def due(self) -> bool:
        """Whether the side has played ``train_every`` turns since its last step."""
        return bool(self.counters[TURNS] - self.counters[PAUSED_AT] >= self.config.train_every)

    def between_calls(self) -> None:
        """Alone: the gradient step and target copy due after ``train_every`` more turns
        (in a batch the group takes them, for every match at once)."""
        if len(self.group.views) == 1:
            self.group.train()

    def freeze(self) -> None:
        """Keep the current weights from now on (the match has finished learning)."""
        if self.frozen:
            return
        self.data = self.data._replace(weights=Weights(*(w.copy() for w in self.data.weights)))
        self.frozen = True

    def memory_bytes(self) -> int:
        share = self.group.memory_bytes() // len(self.group.views)
        return share + sum(a.nbytes for a in self.data.replay)
