"""Games the agents play, one package each, all speaking the compiled game protocol of
:mod:`cmarlcd.games.spec` (kernels + :class:`GameSpec`) and PettingZoo's ``ParallelEnv``
(:class:`cmarlcd.games.env.KernelParallelEnv`)."""

from cmarlcd.games.matrix import (
    MatrixGame,
    climbing_game,
    from_payoffs,
    load_payoffs,
    penalty_game,
    random_case1,
    random_case2,
    random_game,
)
from cmarlcd.games.spec import GameKernels, GameSpec

__all__ = [
    "GameKernels",
    "GameSpec",
    "MatrixGame",
    "climbing_game",
    "from_payoffs",
    "load_payoffs",
    "penalty_game",
    "random_case1",
    "random_case2",
    "random_game",
]
