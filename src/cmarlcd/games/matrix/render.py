"""A text picture of a repeated game: its payoffs and the last joint action played."""

from __future__ import annotations

from collections.abc import Sequence

from cmarlcd.games.matrix.game import MatrixGame


def render_text(game: MatrixGame, joint: Sequence[int] | None = None) -> str:
    """Two agents: the payoff matrix (rows: agent 0) with the played cell in brackets.
    More agents: one line with the joint action and its payoff."""
    header = f"{game.name}: {game.n_agents} agents, actions {game.action_counts}"
    if game.n_agents != 2:
        played = "" if joint is None else f"; played {tuple(joint)} -> {game.payoff(joint):g}"
        return header + played
    cells = [
        [
            f"[{game.payoffs[r, c]:g}]"
            if joint is not None and (r, c) == tuple(joint)
            else f" {game.payoffs[r, c]:g} "
            for c in range(game.payoffs.shape[1])
        ]
        for r in range(game.payoffs.shape[0])
    ]
    width = max(len(text) for row in cells for text in row)
    lines = [header] + [" ".join(text.rjust(width) for text in row) for row in cells]
    return "\n".join(lines)
