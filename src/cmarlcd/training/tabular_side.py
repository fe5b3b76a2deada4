"""A tabular learner as one side of a game (:mod:`cmarlcd.training.loop`).

**Memory.** ``rows[s]`` is state ``s``'s row in the learner's tables (-1 until its first
visit, when the row is initialised with the state's legal actions). A game of at most
:data:`DENSE_STATES` state indices gets one row per index (``rows[s] = s``). A larger one
gets one row per state the side has *visited*: rows are handed out in order of first
visit, and the tables double when they might not hold another episode (the loop stops
before that episode, :meth:`TabularSide.between_calls` grows them, and the loop goes on
with the same streams). So a side of the battlefield, with 802,816 state indices, holds
only the states its play reaches. The learner sees rows only: it learns the same values
either way.

The side kernels are templates bound to the game's kernels (``game``) and the learner's
(``learner``, :class:`cmarlcd.learners.tabular.protocol.TabularKernels`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, shared_kernel, specialise_kernel
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.policy import uniform_legal_action
from cmarlcd.learners.tabular.protocol import TabularConfig, greedy_policy, grow_tables, init_tables
from cmarlcd.training.protocol import Side, SideKernels, never_pause

game = Unbound("game")
learner = Unbound("learner")

#: [choice] Rows a side's tables start with on a large game (they double as more states
#: are visited); a game of at most this many state indices gets one row per index.
INITIAL_ROWS = 4096
DENSE_STATES = INITIAL_ROWS
#: What a tabular side plays at evaluation in a state it never visited while learning
#: (:func:`tabular_greedy`), by name; the first is the default.
UNSEEN_MODES = ("lowest", "random")
LOWEST, RANDOM = range(len(UNSEEN_MODES))


def check_unseen(mode: str) -> int:
    """The code of an unseen-state mode named by the user (one of :data:`UNSEEN_MODES`)."""
    require(
        mode in UNSEEN_MODES,
        "unseen",
        f"must be one of {', '.join(UNSEEN_MODES)} (got {mode!r})",
    )
    return UNSEEN_MODES.index(mode)


class TabularData(NamedTuple):
    """One tabular side's arrays, as the side kernels read them."""

    tables: tuple
    """The learner's tables: one row per state index (dense), or per visited state."""
    params: tuple
    counts: np.ndarray
    """Action counts of the side's agents."""
    rows: np.ndarray
    """``rows[s]``: state ``s``'s row in ``tables``, -1 before its first visit."""
    used: np.ndarray
    """``used[0]``: states visited so far (the rows handed out, when not dense)."""
    states: np.ndarray
    """The episode so far: the row of each turn's state, ..."""
    joints: np.ndarray
    """... the side's joint action at each turn ..."""
    rewards: np.ndarray
    """... and the side's reward after it."""
    unseen: np.ndarray
    """``unseen[0]``: LOWEST or RANDOM, what the side plays in a state it never visited."""
    dense: np.ndarray
    """``dense[0]``: state ``s`` gets row ``s`` (else rows in order of first visit)."""


@shared_kernel  # takes a plug-in's tables: see cmarlcd.compiled.shared_kernel
def tabular_fits(side, max_steps: int) -> bool:
    """One more episode surely fits: it can visit at most ``max_steps + 1`` new states
    (there is a row for every state of a dense side)."""
    return side.dense[0] or side.used[0] + max_steps + 1 <= side.tables[0].shape[0]


def tabular_enter(side, env, team, offset, legal, length, terminal) -> int:
    """Template: the row of the side's state, handed out and initialised with the
    state's masks on its first visit; recorded as turn ``length``'s state. A terminal
    state is never acted in: it gets no row (the learners never read its values)."""
    if terminal:
        return 0
    s = game.state(env, team)
    row = side.rows[s]
    if row < 0:
        row = s if side.dense[0] else side.used[0]
        side.rows[s] = row
        side.used[0] += 1
        game.legal(env, legal)
        n = side.counts.shape[0]
        learner.init_state(side.tables, side.params, row, legal[offset : offset + n], side.counts)
    side.states[length] = row
    return row


def tabular_act(side, row, rng, joint) -> None:
    """Template: the learner's ``act`` at the row."""
    learner.act(side.tables, side.params, row, side.counts, rng, joint)


def tabular_observe(side, t, next_row, terminal) -> None:
    """Template: the learner's ``observe`` of turn ``t``."""
    learner.observe(
        side.tables, side.params, side.states, side.joints, side.rewards, t, next_row, terminal
    )


def tabular_end_episode(side, length) -> None:
    """Template: the learner's ``end_episode``."""
    learner.end_episode(
        side.tables, side.params, side.states, side.joints, side.rewards, length, side.counts
    )


def tabular_greedy(side, env, team, offset, legal, rng, joint) -> None:
    """Template: the learner's greedy joint action. [choice] In a state the side never
    visited while learning, each agent plays its lowest legal action (LOWEST, the default:
    the greedy choice among untouched values, which start equal), or a legal action drawn
    uniformly from ``rng`` at every such visit (RANDOM: a sample of the initial strategy
    of CMARL-CD and of LA-OCA, both uniform over the legal actions)."""
    row = side.rows[game.state(env, team)]
    if row >= 0:
        learner.greedy(side.tables, row, side.counts, joint)
        return
    game.legal(env, legal)
    for i in range(joint.shape[0]):
        if side.unseen[0] == RANDOM:
            joint[i] = uniform_legal_action(legal[offset + i], side.counts[i], rng.random())
        else:
            joint[i] = np.argmax(legal[offset + i])


def tabular_kernels(spec: GameSpec, config: TabularConfig) -> SideKernels:
    """The side kernels of ``config``'s learner on ``spec``."""
    bound: dict[str, Any] = {"game": spec.kernels, "learner": config.kernels}
    return SideKernels(
        tabular_fits,
        specialise_kernel(tabular_enter, **bound),
        specialise_kernel(tabular_act, **bound),
        specialise_kernel(tabular_observe, **bound),
        specialise_kernel(tabular_end_episode, **bound),
        never_pause,
        specialise_kernel(tabular_greedy, **bound),
    )


class TabularSide(Side):
    """A tabular learner on one side: one row per state index on a small game, tables
    that grow with the states it visits on a large one."""

    def __init__(
        self, spec: GameSpec, team: int, config: TabularConfig, unseen: str = UNSEEN_MODES[0]
    ) -> None:
        counts = spec.action_counts[list(spec.teams[team])].copy()
        steps = spec.max_steps
        dense = spec.n_states <= DENSE_STATES
        capacity = spec.n_states if dense else max(INITIAL_ROWS, steps + 1)
        self.spec, self.config = spec, config
        self.kernels = tabular_kernels(spec, config)
        self.data = TabularData(
            init_tables(config, capacity, counts) if dense else config.new_tables(capacity, counts),
            config.params(),
            counts,
            np.full(spec.n_states, -1, dtype=np.int64),
            np.zeros(1, dtype=np.int64),
            np.zeros(steps + 1, dtype=np.int64),
            np.zeros((steps, counts.shape[0]), dtype=np.int64),
            np.zeros(steps),
            np.array([check_unseen(unseen)], dtype=np.int64),
            np.array([dense]),
        )

    def between_calls(self) -> None:
        """Double the tables when one more episode might not fit."""
        data = self.data
        if not data.dense[0] and data.used[0] + self.spec.max_steps + 1 > data.tables[0].shape[0]:
            tables = grow_tables(data.tables, 2 * data.tables[0].shape[0])
            self.data = data._replace(tables=tables)

    def visited(self) -> int:
        return int(self.data.used[0])

    @property
    def seen(self) -> np.ndarray:
        """``seen[s]``: the side has visited state ``s``."""
        return self.data.rows >= 0

    def state_tables(self) -> tuple:
        """The learner's tables with one row per state index (a state never visited
        keeps the row the learner's tables start with)."""
        data = self.data
        if data.dense[0]:
            return data.tables
        tables = init_tables(self.config, self.spec.n_states, data.counts)
        visited = np.flatnonzero(data.rows >= 0)
        for full, part in zip(tables, data.tables, strict=True):
            full[visited] = part[data.rows[visited]]
        return tables

    def greedy_policy(self) -> np.ndarray:
        """The greedy joint action of every state index: (n_states, n_agents)."""
        return greedy_policy(self.config, self.state_tables(), self.data.counts)

    def memory_bytes(self) -> int:
        return sum(a.nbytes for a in self.data.tables) + self.data.rows.nbytes
