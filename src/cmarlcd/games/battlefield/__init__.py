"""The blood battlefield of Section V-B, one module per job: :mod:`~.kernels` (the rules,
the compiled transition and :data:`SPEC`), :mod:`~.env` (the PettingZoo ``ParallelEnv``)
and :mod:`~.render` (a text picture)."""

from cmarlcd.games.battlefield.env import BattlefieldEnv
from cmarlcd.games.battlefield.kernels import (
    GUNNER,
    MARINE,
    PAPER,
    RUNNING,
    SPEC,
    TIE,
    WIN_0,
    WIN_1,
    Battlefield,
    Unit,
    decode_side_state,
    encode_side_state,
    outcome,
)
from cmarlcd.games.battlefield.render import render_text

__all__ = [
    "GUNNER",
    "MARINE",
    "PAPER",
    "RUNNING",
    "SPEC",
    "TIE",
    "WIN_0",
    "WIN_1",
    "Battlefield",
    "BattlefieldEnv",
    "Unit",
    "decode_side_state",
    "encode_side_state",
    "outcome",
    "render_text",
]
