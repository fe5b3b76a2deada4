"""A tabular learner as one side of a match (:mod:`cmarlcd.training.match`).

**Memory.** A side's tables hold one row per state the side has *visited*, not one per
state index: ``rows[s]`` is state ``s``'s row (-1 until its first visit), rows are handed
out in order of first visit, and the tables double when they might not hold another
episode (the loop stops before that episode, :meth:`TabularSide.between_calls` grows
them, and the loop goes on with the same streams). So a side of the battlefield, with
802,816 state indices, holds only the states its play reaches. The learner sees rows
only: it learns the same values as with one row per state index.

The side kernels are templates bound to the game's kernels (``game``) and the learner's
(``learner``, :class:`cmarlcd.learners.tabular.TabularKernels`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from cmarlcd.compiled import Unbound, shared_kernel, specialise
from cmarlcd.errors import require
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.policy import uniform_legal_action
from cmarlcd.learners.tabular import TabularConfig, grow_tables
from cmarlcd.training.match import MatchSide, SideKernels

game = Unbound("game")
learner = Unbound("learner")

#: [choice] Rows a side's tables start with (they double as more states are visited).
INITIAL_ROWS = 4096
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
    """The learner's tables, one row per visited state."""
    params: tuple
    counts: np.ndarray
    """Action counts of the side's agents."""
    rows: np.ndarray
    """``rows[s]``: state ``s``'s row in ``tables``, -1 before its first visit."""
    used: np.ndarray
    """``used[0]``: rows handed out so far."""
    states: np.ndarray
    """The episode so far: the row of each turn's state, ..."""
    joints: np.ndarray
    """... the side's joint action at each turn ..."""
    rewards: np.ndarray
    """... and the side's reward after it."""
    unseen: np.ndarray
    """``unseen[0]``: LOWEST or RANDOM, what the side plays in a state it never visited."""


@shared_kernel  # takes a plug-in's tables: see cmarlcd.compiled.shared_kernel
def tabular_fits(side, max_steps: int) -> bool:
    """One more episode surely fits: it can visit at most ``max_steps + 1`` new states."""
    return side.used[0] + max_steps + 1 <= side.tables[0].shape[0]


def tabular_enter(side, env, team, offset, legal, length) -> int:
    """Template: the row of the side's state, handed out and initialised with the
    state's masks on its first visit; recorded as turn ``length``'s state."""
    s = game.state(env, team)
    row = side.rows[s]
    if row < 0:
        row = side.used[0]
        side.rows[s] = row
        side.used[0] = row + 1
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


@shared_kernel  # takes a plug-in's tables: see cmarlcd.compiled.shared_kernel
def never_pause(side) -> bool:
    """A tabular side learns inside the loop: it never needs to stop it."""
    return False


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
        specialise(tabular_enter, **bound),
        specialise(tabular_act, **bound),
        specialise(tabular_observe, **bound),
        specialise(tabular_end_episode, **bound),
        never_pause,
        specialise(tabular_greedy, **bound),
    )


class TabularSide(MatchSide):
    """A tabular learner on one side: tables that grow with the states it visits."""

    def __init__(
        self, spec: GameSpec, team: int, config: TabularConfig, unseen: str = UNSEEN_MODES[0]
    ) -> None:
        counts = spec.action_counts[list(spec.teams[team])].copy()
        steps = spec.max_steps
        capacity = max(min(INITIAL_ROWS, spec.n_states), steps + 1)
        self.spec, self.config = spec, config
        self.kernels = tabular_kernels(spec, config)
        self.data = TabularData(
            config.new_tables(capacity, counts),
            config.params(),
            counts,
            np.full(spec.n_states, -1, dtype=np.int64),
            np.zeros(1, dtype=np.int64),
            np.zeros(steps + 1, dtype=np.int64),
            np.zeros((steps, counts.shape[0]), dtype=np.int64),
            np.zeros(steps),
            np.array([check_unseen(unseen)], dtype=np.int64),
        )

    def between_calls(self) -> None:
        """Double the tables when one more episode might not fit."""
        data = self.data
        if data.used[0] + self.spec.max_steps + 1 > data.tables[0].shape[0]:
            tables = grow_tables(data.tables, 2 * data.tables[0].shape[0])
            self.data = data._replace(tables=tables)

    def visited(self) -> int:
        return int(self.data.used[0])

    def memory_bytes(self) -> int:
        return sum(a.nbytes for a in self.data.tables) + self.data.rows.nbytes


def new_side(
    spec: GameSpec,
    team: int,
    config: Any,
    rng: np.random.Generator,
    learn_episodes: int,
    unseen: str = UNSEEN_MODES[0],
) -> MatchSide:
    """The side of ``config``'s learner: tabular (playing ``unseen`` in states it never
    visited), or deep (needs the ``[deep]`` extra)."""
    if isinstance(config, TabularConfig):
        return TabularSide(spec, team, config, unseen)
    from cmarlcd.training.deep_side import DeepSide  # needs the [deep] extra

    return DeepSide.alone(spec, team, config, rng, learn_episodes)


def new_sides(
    spec: GameSpec,
    configs: Sequence[Any],
    positions: Sequence[tuple[int, int]],
    agent_rngs: Sequence[Sequence[np.random.Generator]],
    learn_episodes: int,
    unseen: str = UNSEEN_MODES[0],
) -> tuple[list[list[MatchSide]], list[Any]]:
    """The sides of a batch of matches (see :class:`cmarlcd.training.match.MatchBatch`):
    per match its two sides, and the groups that train the deep positions together
    (``unseen``: what the tabular sides play in states they never visited)."""
    matches: list[list[MatchSide | None]] = [[None, None] for _ in positions]
    groups = []
    for p, config in enumerate(configs):
        seats = [(m, order.index(p)) for m, order in enumerate(positions)]
        if isinstance(config, TabularConfig):
            for m, team in seats:
                matches[m][team] = TabularSide(spec, team, config, unseen)
            continue
        from cmarlcd.training.deep_side import DeepGroup  # needs the [deep] extra

        rngs = [agent_rngs[m][team] for m, team in seats]
        group = DeepGroup(spec, [team for _, team in seats], config, rngs, learn_episodes)
        groups.append(group)
        for (m, team), view in zip(seats, group.views, strict=True):
            matches[m][team] = view
    return matches, groups  # type: ignore[return-value]
