"""A text picture of the DSN grid: targets with their energy, and who focuses where."""

from __future__ import annotations

import numpy as np

from cmarlcd.games.sensor_network.kernels import (
    IDLE,
    N_CELLS,
    N_COLS,
    N_ROWS,
    N_TARGETS,
    SENSOR_CELLS,
    validate_joint,
)

_CELL_WIDTH = 13


def render_text(targets: np.ndarray, energy: np.ndarray, joint: np.ndarray | None = None) -> str:
    """A text picture of the grid: each cell's target (``T0 e=3``) and, when ``joint`` is
    given, the sensors focusing it (``s1,s4,s5``); then the captured targets."""
    border = "+" + "+".join(["-" * _CELL_WIDTH] * N_COLS) + "+"
    focus: list[list[int]] = [[] for _ in range(N_CELLS)]
    if joint is not None:
        for s, action in enumerate(validate_joint(joint)):
            if action != IDLE:
                focus[SENSOR_CELLS[s, action - 1]].append(s)
    lines = [border]
    for row in range(N_ROWS):
        top, bottom = [], []
        for cell in range(row * N_COLS, (row + 1) * N_COLS):
            here = [k for k in range(N_TARGETS) if targets[k] == cell]
            label = " ".join(f"T{k} e={int(energy[k])}" for k in here) or f"c{cell}"
            top.append(f" {label:<{_CELL_WIDTH - 1}}")
            seen = ",".join(f"s{s}" for s in focus[cell]) if focus[cell] else ""
            bottom.append(f" {seen:<{_CELL_WIDTH - 1}}")
        lines += ["|" + "|".join(top) + "|", "|" + "|".join(bottom) + "|", border]
    captured = [f"T{k}" for k in range(N_TARGETS) if targets[k] < 0]
    lines.append("captured: " + (", ".join(captured) if captured else "none"))
    return "\n".join(lines)
