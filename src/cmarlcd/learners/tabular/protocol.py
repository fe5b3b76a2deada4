"""The tabular learner protocol, and the object API every tabular learner shares.

A tabular learner for stochastic games keeps, per state index ``s`` and agent ``i``, a row
over the agent's actions (padded to the widest action count) in its *tables*: a
NamedTuple of arrays with a leading state axis, one of them ``legal`` (the state's
legal-action masks). Its compiled functions, written once in the learner's own file and
called alike by the compiled training loops (:mod:`cmarlcd.training.tabular`) and by
:class:`TabularLearner`, are

==============================================  ===============================================
``init_state(tables, params, s, legal, counts)``  state ``s`` before any update (``legal``:
                                                   ``(n_agents, width)`` masks)
``act(tables, params, s, counts, rng, joint)``    sample the joint action played in ``s``
``greedy(tables, s, counts, joint)``              execution: each agent's greedy legal action
``observe(tables, params, states, joints,         after every step (learners that bootstrap):
rewards, t, next_s, terminal)``                   step ``t`` of the episode so far led to
                                                   ``next_s`` (initialised unless terminal)
``end_episode(tables, params, states, joints,     after every episode (Monte-Carlo learners)
rewards, length, counts)``
==============================================  ===============================================

Both hooks read the episode from ``states[t]``, ``joints[t]`` and ``rewards[t]`` (the
state, the joint action and the reward that followed), so the loops pass whole arrays
and never build a view per step.

``params`` is the learner's NamedTuple of compiled parameters, made by its config. A
learner's frozen config (:class:`TabularConfig`) names the learner and carries these
functions, so a config alone says what to train.

Repeated games (Algorithm 1) have their own, smaller protocol (:class:`RepeatedKernels`):
one state, and the loop plays until the learner says it has converged.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from typing import Any, ClassVar, NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, shared_kernel, specialise
from cmarlcd.errors import require


class TabularKernels(NamedTuple):
    """A tabular learner's compiled functions (see the module docstring)."""

    init_state: Any
    act: Any
    greedy: Any
    observe: Any
    end_episode: Any


class RepeatedKernels(NamedTuple):
    """A learner for repeated games: ``act(tables, params, counts, rng, joint)``,
    ``learn(tables, params, counts, joint, reward) -> changed``, ``converged(tables,
    params, counts)`` (asked only after a change) and ``greedy(tables, counts, joint)``."""

    act: Any
    learn: Any
    converged: Any
    greedy: Any


class TabularConfig:
    """Base of the frozen configs of tabular learners for stochastic games.

    A subclass is a frozen dataclass of the learner's hyper-parameters that sets
    :attr:`name`, :attr:`display_name` and :attr:`kernels` and implements :meth:`params`
    and :meth:`new_tables`.
    """

    name: ClassVar[str]
    """The learner's registry name (``"cmarl-cd"``)."""
    display_name: ClassVar[str]
    """The learner's name in tables and figures (``"CMARL-CD"``)."""
    kernels: ClassVar[TabularKernels]
    """The learner's compiled functions."""

    def params(self) -> tuple:
        """The compiled parameters (a NamedTuple of numbers)."""
        raise NotImplementedError

    def new_tables(self, n_states: int, counts: np.ndarray) -> tuple:
        """Zeroed tables for ``n_states`` states; :func:`init_tables` fills them."""
        raise NotImplementedError


@shared_kernel
def no_step_update(tables, params, states, joints, rewards, t, next_s, terminal) -> None:
    """``observe`` of a learner that learns from whole episodes only."""


@shared_kernel
def no_episode_update(tables, params, states, joints, rewards, length, counts) -> None:
    """``end_episode`` of a learner that learns from single steps only."""


def full_legal(counts: np.ndarray) -> np.ndarray:
    """Masks with every real action legal: ``(n_agents, width)`` bool."""
    return np.arange(int(counts.max()))[None, :] < counts[:, None]


learner = Unbound("learner")


def init_every_state(tables, params, legal, counts) -> None:
    """Template: every state of ``tables`` set up with the masks ``legal``."""
    for s in range(tables[0].shape[0]):
        learner.init_state(tables, params, s, legal, counts)


def greedy_every_state(tables, counts, policy) -> None:
    """Template: ``policy[s]`` := the greedy joint action of every state ``s``."""
    for s in range(policy.shape[0]):
        learner.greedy(tables, s, counts, policy[s])


def init_tables(config: TabularConfig, n_states: int, counts: np.ndarray) -> tuple:
    """New tables with every state initialised as if every action were legal (a state's
    first visit initialises it again with its real masks)."""
    tables = config.new_tables(n_states, counts)
    loop = specialise(init_every_state, learner=config.kernels)
    loop(tables, config.params(), full_legal(counts), counts)
    return tables


def greedy_policy(config: TabularConfig, tables: tuple, counts: np.ndarray) -> np.ndarray:
    """The greedy joint action of every state: shape (n_states, n_agents)."""
    policy = np.zeros((tables[0].shape[0], counts.shape[0]), dtype=np.int64)
    specialise(greedy_every_state, learner=config.kernels)(tables, counts, policy)
    return policy


def grow_tables(tables: tuple, n_states: int) -> tuple:
    """``tables`` with room for ``n_states`` states (new rows zero, uninitialised)."""
    return type(tables)(
        *(np.pad(a, [(0, n_states - a.shape[0])] + [(0, 0)] * (a.ndim - 1)) for a in tables)
    )


class TabularLearner:
    """The object API of a tabular learner for stochastic games, over its compiled functions.

    States are integers in ``[0, n_states)`` when ``n_states`` is given, otherwise any
    hashable value, mapped to table rows in order of first visit. ``masks`` is one
    legal-action mask per agent (1 = legal); ``None`` means every action is legal. A
    state's masks are recorded on its first visit.

    Use: ``joint = act(state, masks)``, ``observe(state, joint, reward)`` after each step,
    ``end_episode(final_state, terminated)`` after each episode; ``greedy(state)`` for
    execution. Several copies of the environment may be played at once: ``copy`` (0 by
    default) tells whose episode a call belongs to, and each copy's episode is learned
    from when it ends. With the same seeds this learns exactly what the compiled loop of
    :mod:`cmarlcd.training.tabular` learns (the same functions, called in the same order).
    """

    default_config: ClassVar[TabularConfig | None] = None
    """The config used when none is given (a learner's subclass sets its own)."""

    def __init__(
        self,
        action_counts: Sequence[int],
        config: TabularConfig | None = None,
        n_states: int | None = None,
        seed: int | np.random.SeedSequence | np.random.Generator | None = None,
    ) -> None:
        config = config or self.default_config
        require(
            config is not None, "config", "names the learner; give one (e.g. StochasticConfig())"
        )
        counts = [int(k) for k in action_counts]
        require(len(counts) >= 1, "agents", "needs at least one agent")
        require(min(counts) >= 1, "actions", f"every agent needs >= 1 action (got {counts})")
        require(n_states is None or n_states >= 1, "n_states", f"must be >= 1 (got {n_states})")
        self.config = config
        self.params = config.params()
        self.counts = np.array(counts, dtype=np.int64)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._index: dict[Hashable, int] | None = None if n_states else {}
        self.tables = init_tables(config, n_states or 16, self.counts)
        self._seen = np.zeros(self.n_states, dtype=np.bool_)
        self._episodes: dict[int, list[tuple[int, np.ndarray, float]]] = {}
        self._pending: dict[int, tuple[int, np.ndarray, float]] = {}

    @property
    def n_agents(self) -> int:
        return int(self.counts.shape[0])

    @property
    def n_states(self) -> int:
        """Rows in the tables (grows with hashable states)."""
        return int(self.tables[0].shape[0])

    def act(
        self, state: Hashable, masks: Sequence[np.ndarray] | None = None, copy: int = 0
    ) -> tuple[int, ...]:
        """Sample a joint action from the strategies at ``state`` (in ``copy``'s episode)."""
        row = self._row(state, masks)
        self._complete(copy, row, terminal=False)
        joint = np.zeros(self.n_agents, dtype=np.int64)
        self.config.kernels.act(self.tables, self.params, row, self.counts, self.rng, joint)
        return tuple(joint.tolist())

    def observe(
        self, state: Hashable, joint_action: Sequence[int], reward: float, copy: int = 0
    ) -> None:
        """Record one step of ``copy``'s episode: ``joint_action`` at ``state`` was
        followed by ``reward``."""
        joint = np.asarray(joint_action, dtype=np.int64)
        require(joint.shape == (self.n_agents,), "joint_action", f"needs {self.n_agents} actions")
        require(math.isfinite(reward), "reward", f"must be finite (got {reward})")
        step = (self._row(state, None), joint, float(reward))
        self._episodes.setdefault(copy, []).append(step)
        self._pending[copy] = step

    def end_episode(
        self, final_state: Hashable = None, terminated: bool = True, copy: int = 0
    ) -> None:
        """Learn from ``copy``'s recorded episode and start a new one there.
        ``final_state`` (reached by the last step) is bootstrapped from unless
        ``terminated``."""
        if copy in self._pending:
            known = final_state is not None and not terminated
            row = self._row(final_state, None) if known else None
            self._complete(copy, row, terminal=not known)
        episode = self._episodes.pop(copy, [])
        if not episode:
            return
        rows, joints, rewards = zip(*episode, strict=True)
        self.config.kernels.end_episode(
            self.tables,
            self.params,
            np.array(rows, dtype=np.int64),
            np.stack(joints),
            np.array(rewards),
            len(rows),
            self.counts,
        )

    def _complete(self, copy: int, next_row: int | None, terminal: bool) -> None:
        """Hand ``copy``'s step waiting for its successor to the learner's ``observe``."""
        if copy not in self._pending:
            return
        row, joint, reward = self._pending.pop(copy)
        if self.config.kernels.observe is no_step_update:
            return  # a learner of whole episodes: nothing to do per step
        successor = row if next_row is None else next_row
        states, rewards = np.array([row], dtype=np.int64), np.array([reward])
        self.config.kernels.observe(
            self.tables, self.params, states, joint[None], rewards, 0, successor, terminal
        )

    def greedy(self, state: Hashable, masks: Sequence[np.ndarray] | None = None) -> tuple[int, ...]:
        """Execution: each agent's greedy legal action at ``state``."""
        row = self._row(state, masks)
        joint = np.zeros(self.n_agents, dtype=np.int64)
        self.config.kernels.greedy(self.tables, row, self.counts, joint)
        return tuple(joint.tolist())

    def _lookup(self, state: Hashable) -> int | None:
        if self._index is None:
            row = int(state)  # type: ignore[call-overload]
            require(0 <= row < self.n_states, "state", f"must be in [0, {self.n_states})")
            return row if self._seen[row] else None
        return self._index.get(state)

    def _row(self, state: Hashable, masks: Sequence[np.ndarray] | None) -> int:
        row = self._lookup(state)
        if row is not None:
            return row
        if self._index is None:
            row = int(state)  # type: ignore[call-overload]
        else:
            row = len(self._index)
            if row == self.n_states:
                self.tables = grow_tables(self.tables, 2 * row)
                self._seen = np.pad(self._seen, (0, row))
            self._index[state] = row
        self._seen[row] = True
        legal = self._mask_array(masks)
        self.config.kernels.init_state(self.tables, self.params, row, legal, self.counts)
        return row

    def _mask_array(self, masks: Sequence[np.ndarray] | None) -> np.ndarray:
        legal = full_legal(self.counts)
        if masks is not None:
            require(len(masks) == self.n_agents, "masks", "needs one mask per agent")
            for i, mask in enumerate(masks):
                mask = np.asarray(mask, dtype=bool)
                require(mask.shape == (self.counts[i],), "masks", f"agent {i}: wrong length")
                require(bool(mask.any()), "masks", f"agent {i} has no legal action")
                legal[i, : self.counts[i]] = mask
        return legal


class MaxReturnLearner(TabularLearner):
    """The object API of a learner driven by the max-return indicator."""

    def max_return(self, state) -> float:
        """``R_max(state)``: the best discounted return seen from it (``-inf`` if unseen)."""
        row = self._lookup(state)
        return -np.inf if row is None else float(self.tables.r_max[row])
