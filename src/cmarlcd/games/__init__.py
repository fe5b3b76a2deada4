"""Games the agents play."""

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

__all__ = [
    "MatrixGame",
    "climbing_game",
    "from_payoffs",
    "load_payoffs",
    "penalty_game",
    "random_case1",
    "random_case2",
    "random_game",
]
