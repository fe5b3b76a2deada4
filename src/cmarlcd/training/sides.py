"""The side of each learner: tabular, or deep (``[deep]`` extra, imported only then).

:func:`new_side` makes one side; :func:`new_sides` the sides of a batch of matches, with
the groups in which each deep learner's sides train as one stacked model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.tabular.protocol import TabularConfig
from cmarlcd.training.loop import Group
from cmarlcd.training.protocol import Side
from cmarlcd.training.tabular_side import UNSEEN_MODES, TabularSide


def new_side(
    spec: GameSpec,
    team: int,
    config: Any,
    rng: np.random.Generator,
    learn_episodes: int,
    unseen: str = UNSEEN_MODES[0],
) -> Side:
    """The side of ``config``'s learner on team ``team``: tabular (playing ``unseen`` in
    states it never visited), or deep (its streams spawned from ``rng``)."""
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
) -> tuple[list[list[Side]], list[Group]]:
    """The sides of a batch of matches (see :class:`cmarlcd.training.match.MatchBatch`):
    per match its two sides, and the groups that train the deep positions together
    (``unseen``: what the tabular sides play in states they never visited)."""
    matches: list[list[Side | None]] = [[None, None] for _ in positions]
    groups: list[Group] = []
    for p, config in enumerate(configs):
        seats = [(m, order.index(p)) for m, order in enumerate(positions)]
        if isinstance(config, TabularConfig):
            for m, team in seats:
                matches[m][team] = TabularSide(spec, team, config, unseen)
            continue
        from cmarlcd.training.deep_side import DeepGroup, streams_of  # needs [deep]

        init, replay = streams_of([agent_rngs[m][team] for m, team in seats])
        teams = [team for _, team in seats]
        group = DeepGroup(spec, teams, config, init, replay, learn_episodes)
        groups.append(group)
        for (m, team), view in zip(seats, group.views, strict=True):
            matches[m][team] = view
    return matches, groups  # type: ignore[return-value]
