"""A text picture of a Level-Based Foraging grid."""

from __future__ import annotations

from cmarlcd.games.foraging.kernels import COL, LEVEL, ROW


def render_text(env: tuple, step: int) -> str:
    """The grid, one row a line: ``.`` an empty cell, a food's level as a digit (``*``
    from 10), an agent as a letter (``A`` agent 0 ...); then each agent's level."""
    players, field = env[0], env[1]
    rows, cols = field.shape
    cells = [["." if field[r, c] == 0 else _digit(int(field[r, c])) for c in range(cols)]
             for r in range(rows)]  # fmt: skip
    for i in range(players.shape[0]):
        r, c = int(players[i, ROW]), int(players[i, COL])
        if 0 <= r < rows and 0 <= c < cols:
            cells[r][c] = chr(ord("A") + i)
    levels = " ".join(f"{chr(ord('A') + i)}:{int(players[i, LEVEL])}" for i in range(len(players)))
    return "\n".join([f"step {step}", *(" ".join(row) for row in cells), f"levels {levels}"])


def _digit(level: int) -> str:
    return str(level) if level < 10 else "*"
