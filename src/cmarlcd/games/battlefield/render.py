"""A text picture of a battle: both troops' HP, and each turn's attacks."""

from __future__ import annotations

import numpy as np

from cmarlcd.games.battlefield.kernels import (
    HIT,
    HP,
    N_SIDES,
    NO_TARGET,
    OUTCOME,
    TARGET,
    TIE,
    TURN,
    WIN_0,
    WIN_1,
)

_OUTCOMES = {WIN_0: "side 0 wins", WIN_1: "side 1 wins", TIE: "tie (both wiped out)"}


def unit_label(kind: str, slot: int) -> str:
    """``M0``..``M3`` for marines, ``G4``, ``G5`` for gunners (the slot is the action)."""
    return f"{kind[0].upper()}{slot}"


def render_text(env: tuple, kinds: list[str], max_turns: int | None = None) -> str:
    """Each side's units with their HP (``M0 3/3``, ``x`` once destroyed), then last
    turn's attacks (``M0->G5 hit``) and, once the game is over, the outcome (a game
    still running after ``max_turns`` turns is a tie)."""
    hp, stats, _, _, log, status = env
    n = hp.shape[1]
    lines = [f"turn {int(status[TURN])}"]
    for k in range(N_SIDES):
        units = []
        for u in range(n):
            label = unit_label(kinds[u], u)
            life = f"{int(hp[k, u])}/{int(stats[HP, u])}" if hp[k, u] > 0 else "x"
            units.append(f"{label} {life}")
        lines.append(f"side {k}: " + "  ".join(units))
    if status[TURN] > 0:
        for k in range(N_SIDES):
            lines.append(f"side {k} fired: " + (_attacks(log[k], kinds) or "-"))
    finished = _OUTCOMES.get(int(status[OUTCOME]))
    if finished is None and max_turns is not None and status[TURN] >= max_turns:
        finished = f"tie ({max_turns} turns)"
    if finished:
        lines.append(finished)
    return "\n".join(lines)


def _attacks(log: np.ndarray, kinds: list[str]) -> str:
    shots = []
    for u in range(log.shape[1]):
        target = int(log[TARGET, u])
        if target == NO_TARGET:
            continue
        result = "hit" if log[HIT, u] else "miss"
        shots.append(f"{unit_label(kinds[u], u)}->{unit_label(kinds[target], target)} {result}")
    return ", ".join(shots)
