"""A deep learner as one side of a game (:mod:`cmarlcd.training.loop`; ``[deep]``
extra): VDN or QMIX, or deep CMARL-CD. What differs between them is behind their config
(:class:`cmarlcd.learners.deep.config.DeepLearnerConfig`): its compiled side kernels (how
it acts and what it stores in its replay ring) and its stacked model (what a gradient
step does); the rest, written here once, is the same for every deep learner.

A deep side sees its state in one of two ways ([choice] the game's feature vector where it
has one, else the state index):

* **features** (``game.features``; the battlefield's 802,816 states per side are far too
  many for one-hot inputs): inside the compiled loop the side acts with its agent
  networks' forward pass, compiled over a copy of their weights
  (:mod:`cmarlcd.training.deep_kernels`);
* **index** (one-hot state indices; the DSN's 43): the networks' Q-values of every state
  form a table, copied after each gradient step, and the side acts by looking it up.

Either way it acts with its learner's kernels (VDN and QMIX ε-greedily, eq. 18, each
turn appended to the replay ring; deep CMARL-CD by softmax over its degrees, each
episode's visits stored when it ends). Every ``train_every`` turns it pauses the loop,
and its :class:`DeepGroup` takes the gradient step and target copy the schedule asks for
(:func:`cmarlcd.learners.deep.config.scheduled_work`) on the learner's stacked model
(:class:`~cmarlcd.learners.deep.value_decomposition.ValueDecomposition`,
:class:`~cmarlcd.learners.deep.degree_model.DegreeModel`), then copies the new weights (or
tables) back for the loop. The networks change only there, so acting with
the copy is acting with the networks.

A group holds the deep sides of B plays (the rounds of a tournament pairing, the seeds of a
DSN row), one seed each, with its own parameters, replay ring and streams; the B seeds
take their gradient steps together. A play alone is a group of one.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from cmarlcd import devices
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.config import (
    EPISODES_UNIT,
    OWN_OBSERVATION_LEARNERS,
    STEPS_UNIT,
    DeepConfig,
    DeepLearnerConfig,
    scheduled_work,
)
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.degree_model import DegreeModel
from cmarlcd.learners.deep.fused.networks import own_starts
from cmarlcd.learners.deep.threads import intra_op_threads
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition
from cmarlcd.learners.tabular.protocol import full_legal
from cmarlcd.plugins import note
from cmarlcd.training.deep_kernels import (
    ENDED_TERMINAL,
    GENERATION,
    GREEDY_CACHE_SLOTS,
    INPUTS,
    NEW_STATES,
    PAUSED_AT,
    TURNS,
    FeatureData,
    GreedyCache,
    IndexData,
    Weights,
    deep_kernels,
    hidden_scratch,
    inputs_of,
)
from cmarlcd.training.deep_replay import BOOTSTRAPPED, KEYED, RING
from cmarlcd.training.degree_kernels import degree_kernels
from cmarlcd.training.loop import BUDGET_UNITS, Group
from cmarlcd.training.protocol import Side, SideKernels

# ------------------------------------------------------------------ learners

#: Each deep learner's parts, by its config's type: its side kernels (from the game, the
#: inputs and the config), its stacked model (from the action counts, the input size,
#: the config and the seeds) and its replay kind (from the config;
#: :mod:`cmarlcd.training.deep_replay`).
DEEP_LEARNERS: dict[type, tuple[Callable, Callable, Callable]] = {}


def register_deep_learner(
    config_type: type, kernels: Callable, model: Callable, replay: Callable = lambda config: RING
) -> None:
    """Let the deep side play the learner whose config is a ``config_type`` (a
    :class:`~cmarlcd.learners.deep.config.DeepLearnerConfig`): a plug-in deep learner
    registers itself once, in its own module (its replay: a ring of transitions unless
    it says otherwise). Called at the top level of a module, it registers the learner in
    the sweep's worker processes too (:mod:`cmarlcd.plugins`)."""
    DEEP_LEARNERS[config_type] = (kernels, model, replay)
    note("deep learner", f"{config_type.__module__}.{config_type.__qualname__}")


def parts_of(config: DeepLearnerConfig) -> tuple[Callable, Callable, Any]:
    """The side kernels, the model and the replay kind of ``config``'s learner."""
    for config_type, (kernels, model, replay) in DEEP_LEARNERS.items():
        if isinstance(config, config_type):
            return kernels, model, replay(config)
    raise TypeError(f"{type(config).__name__} is no registered deep learner")


def degree_replay(config: DeepCMARLCDConfig) -> Any:
    """Deep CMARL-CD's keyed memory, or a ring of visits for its ``replayed`` and
    ``imitation`` updates (with the record network to bootstrap from, for λ-returns)."""
    if config.keyed:
        return KEYED
    return BOOTSTRAPPED if config.bootstraps else RING


register_deep_learner(DeepConfig, deep_kernels, ValueDecomposition)
register_deep_learner(DeepCMARLCDConfig, degree_kernels, DegreeModel, degree_replay)

# ------------------------------------------------------------------ groups


class DeepGroup(Group):
    """A deep learner's sides of B plays, trained as one stacked model: one seed per play,
    each with its own parameters, replay ring and streams.

    Each play's side is a :class:`DeepSide` view of the group's stacked arrays. Seed b's
    parameters are initialised from ``init_seeds[b]`` and its replay batches drawn with
    ``replay_rngs[b]``; its actions come from the play's stream for the side, so a play
    learns the same whether it is batched or alone.

    Plays pause at the same turn counts (every ``train_every`` turns of each), so while
    they all learn, one step of the stacked model is each one's step. A side whose play
    has finished learning keeps (:meth:`DeepSide.freeze`) what it finished with.

    Args:
        spec: the game.
        teams: the team each seed's side plays.
        config: the learner.
        init_seeds: each seed's parameter stream.
        replay_rngs: each seed's replay stream.
        learn_episodes: each play's learning stage (ε is annealed over it).
        inputs: what the sides read (default: :func:`inputs_of` the game).
        device: where the stacked model computes (default: this process's,
            :func:`cmarlcd.devices.current`). Its replay ring stays in host memory, where
            the compiled loop writes it; each gradient step sends its batch over, and the
            loop's copy of the weights (or Q-table) comes back after it.
    """

    def __init__(
        self,
        spec: GameSpec,
        teams: Sequence[int],
        config: DeepLearnerConfig,
        init_seeds: Sequence[np.random.SeedSequence],
        replay_rngs: Sequence[np.random.Generator],
        learn_episodes: int,
        inputs: str | None = None,
        device: str | None = None,
        unit: str = "episodes",
    ) -> None:
        require(unit in BUDGET_UNITS, "unit", f"must be one of {BUDGET_UNITS} (got {unit!r})")
        inputs = inputs_of(spec) if inputs is None else inputs
        require(inputs in INPUTS, "inputs", f"must be one of {', '.join(INPUTS)} (got {inputs!r})")
        counts = spec.action_counts[list(spec.teams[teams[0]])].copy()
        same = all(np.array_equal(spec.action_counts[list(spec.teams[t])], counts) for t in teams)
        require(same, "teams", "one stacked model needs sides with the same action counts")
        seeds, n, width = len(teams), counts.shape[0], int(counts.max())
        features = spec.n_features if inputs == "features" else 0
        self.config, self.spec, self.inputs = config, spec, inputs
        self.alone = False
        """Whether the group trains itself between loop calls (a play on its own) rather
        than when its batch says (:class:`cmarlcd.training.loop.PlayBatch`)."""
        self.last_loss: float | None = None  # the latest gradient step's (live curves)
        new_kernels, new_model, self.replay_kind = parts_of(config)
        device = devices.current() if device is None else device
        # the agents of the learners that can read their own observation do where the
        # game lays the features out so (GameSpec.own_dim); other learners read them whole
        own = spec.own_dim if features and config.name in OWN_OBSERVATION_LEARNERS else 0
        self.own_dim = own
        mine = {"own_dim": own} if own else {}
        self.model = new_model(
            counts, features or spec.n_states, config, init_seeds, device, **mine
        )
        self.replay_rngs = list(replay_rngs)
        self.ring = self.replay_kind.new(config, seeds, counts, spec, features)
        """Every seed's replay (a ring of transitions, or a learner's own kind)."""
        if inputs == "features":
            # (seeds * n, own or features, hidden), ... as the networks lay them out
            self.weights = Weights(
                *(np.zeros(tuple(w.shape), np.float32) for w in self.model.agents.feature_weights())
            )
            if getattr(config, "shares", False) and config.bootstraps:  # from their copy
                copy = Weights(*(np.zeros_like(w) for w in self.weights))
                self.ring = self.ring._replace(record_weights=copy)
        else:
            self.values = np.zeros((seeds, spec.n_states, n, width), np.float32)
            every = full_legal(counts)
            self.legal = np.repeat(np.repeat(every[None], spec.n_states, 0)[None], seeds, 0)
            """Each seed's masks of each state, read when the seed first meets it."""
            self.seen = np.zeros((seeds, spec.n_states), np.bool_)
            """The states each seed has met."""
            self.model.set_state_legal(torch.from_numpy(self.legal))  # on a CPU: shared
        kernels = new_kernels(spec, inputs, config)
        self.views = [
            DeepSide(self, b, counts, kernels, learn_episodes, unit) for b in range(len(teams))
        ]
        self._copy_weights()
        self.replay_kind.refresh(self.ring, self.model, inputs)

    def train(self) -> None:
        """The gradient step and target copy due once the learning sides have played
        ``train_every`` more turns (all of them: they pause at the same turn counts)."""
        due = [view for view in self.views if view.due()]
        if not due:
            return
        learning = [view for view in self.views if not view.frozen]
        if not all(view.due() for view in learning):
            raise RuntimeError("the plays of one batch must pause together")
        before, after = int(due[0].counters[PAUSED_AT]), int(due[0].counters[TURNS])
        for view in due:
            view.counters[PAUSED_AT] = view.counters[TURNS]
        self.masks_changed()
        stored = min(self.replay_kind.stored(self.ring, view.index) for view in due)
        step, copy = scheduled_work(before, after, stored, self.config)
        with intra_op_threads(self.model.step_threads()):
            if step:
                self.last_loss = self.model.learn(self.sample())
                self._copy_weights()
            if copy:
                self.model.sync_target()
                self.replay_kind.target_copied(self.ring, self.model, self.inputs)
            if step or copy:  # after the target copy, which the shares bootstrap from
                self.replay_kind.refresh(self.ring, self.model, self.inputs)

    def masks_changed(self) -> None:
        """Tell the model when a side has read the masks of a new state (index inputs:
        on a CPU the model's per-state masks share the group's memory, on a GPU they are
        sent again; either way its cached target values must be recomputed)."""
        if self.inputs != "index":
            return
        if any(view.counters[NEW_STATES] for view in self.views):
            self.model.set_state_legal(torch.from_numpy(self.legal))
            for view in self.views:
                view.counters[NEW_STATES] = 0

    def sample(self) -> dict[str, torch.Tensor]:
        """A replay batch per seed, drawn with that seed's own generator."""
        batch = self.replay_kind.draw(self.ring, self.replay_rngs, self.config.batch_size)
        device = self.model.device
        return {key: torch.from_numpy(array).to(device) for key, array in batch.items()}

    def greedy_tables(self) -> np.ndarray:
        """(B, n_states, n_agents) (index inputs): each seed's greedy joint action in every
        state, over the masks it has read (including those read since the last step)."""
        self.masks_changed()
        table = self.model.greedy_table().cpu().numpy()
        return self.replay_kind.greedy_table(self.ring, table, self.legal, self.config)

    def _copy_weights(self) -> None:
        """The loops' copy of the networks := the networks (a new generation of
        weights: the greedy actions cached so far are no longer read)."""
        for view in self.views:
            view.counters[GENERATION] += 1
        agents = self.model.agents
        with torch.no_grad():
            if self.inputs == "index":
                agents.copy_tables(self.values)
                return
            for copy, weight in zip(self.weights, agents.feature_weights(), strict=True):
                np.copyto(copy, weight.cpu().numpy())

    def memory_bytes(self) -> int:
        """Parameters (online and target networks, Adam's two moments)."""
        return 4 * sum(p.numel() * p.element_size() for p in self.model.parameters())


class DeepSide(Side):
    """A deep learner on one side of one play: a view of seed ``index`` of a
    :class:`DeepGroup` (alone, a group of one trains itself between loop calls)."""

    def __init__(
        self,
        group: DeepGroup,
        index: int,
        counts: np.ndarray,
        kernels: SideKernels,
        learn_episodes: int,
        unit: str = "episodes",
    ) -> None:
        config, spec = group.config, group.spec
        n, width, steps = counts.shape[0], int(counts.max()), spec.max_steps
        self.group, self.index, self.kernels, self.frozen = group, index, kernels, False
        replay = group.replay_kind.view(group.ring, index)
        counters = np.zeros(ENDED_TERMINAL + 1, np.int64)  # every entry up to the last
        by_steps = unit == "steps" or config.explores_by_steps
        counted = STEPS_UNIT if by_steps else EPISODES_UNIT
        schedule = np.array([*config.schedule(learn_episodes), counted], np.float64)
        joints, rewards = np.zeros((steps, n), np.int64), np.zeros(steps)
        self.data: FeatureData | IndexData
        if group.inputs == "features":
            agents = slice(index * n, (index + 1) * n)
            self.data = FeatureData(
                counts,
                Weights(*(array[agents] for array in group.weights)),
                hidden_scratch(group.weights),
                np.zeros((steps + 2, spec.n_features), np.float32),  # + the greedy row
                np.zeros((steps + 1, n, width), np.bool_),
                joints,
                rewards,
                replay,
                counters,
                schedule,
                np.zeros((2, width)),
                new_greedy_cache(spec, n),
                own_starts(spec.n_features, n, group.own_dim),
            )
        else:
            self.data = IndexData(
                counts,
                group.values[index],
                group.legal[index],
                group.seen[index],
                np.zeros(steps + 1, np.int64),
                joints,
                rewards,
                replay,
                counters,
                schedule,
                np.zeros((2, width)),
            )

    @classmethod
    def alone(
        cls,
        spec: GameSpec,
        team: int,
        config: DeepLearnerConfig,
        rng: np.random.Generator,
        learn_episodes: int,
    ) -> DeepSide:
        """The deep side of a play on its own, its parameter and replay streams spawned
        from its action stream ``rng``."""
        init, replay = streams_of([rng])
        group = DeepGroup(spec, [team], config, init, replay, learn_episodes)
        group.alone = True
        return group.views[0]

    @property
    def counters(self) -> np.ndarray:
        return self.data.counters

    @property
    def model(self):
        return self.group.model

    @property
    def config(self) -> DeepLearnerConfig:
        return self.group.config

    def due(self) -> bool:
        """Whether the side has played ``train_every`` more turns since its last step."""
        return bool(self.counters[TURNS] - self.counters[PAUSED_AT] >= self.config.train_every)

    def between_calls(self) -> None:
        """Alone: the gradient step and target copy due after ``train_every`` more turns
        (in a batch the group takes them, for every play at once)."""
        if self.group.alone:
            self.group.train()

    def freeze(self) -> None:
        """Keep the current weights (or Q-table) from now on."""
        if self.frozen:
            return
        data = self.data
        if isinstance(data, FeatureData):
            self.data = data._replace(weights=Weights(*(w.copy() for w in data.weights)))
        else:
            self.data = data._replace(values=data.values.copy())
        self.frozen = True

    def memory_bytes(self) -> int:
        share = self.group.memory_bytes() // len(self.group.views)
        return share + self.group.replay_kind.nbytes(self.data.replay)


def new_greedy_cache(spec: GameSpec, n_agents: int) -> GreedyCache:
    """A side's empty greedy cache: :data:`GREEDY_CACHE_SLOTS` slots where the game's
    state determines its features, else none."""
    slots = GREEDY_CACHE_SLOTS if spec.state_determines_features else 0
    return GreedyCache(
        np.full(slots, -1, np.int64),
        np.zeros(slots, np.int64),
        np.full((slots, n_agents), -1, np.int32),
        np.zeros(spec.max_steps + 1 if slots else 0, np.int64),
    )


def streams_of(
    rngs: Sequence[np.random.Generator],
) -> tuple[list[np.random.SeedSequence], list[np.random.Generator]]:
    """Each deep side's parameter seed and replay stream, spawned from its action stream
    (a match's sides: see :mod:`cmarlcd.training.sides`)."""
    children = [rng.bit_generator.seed_seq.spawn(2) for rng in rngs]
    return [c[0] for c in children], [np.random.default_rng(c[1]) for c in children]
