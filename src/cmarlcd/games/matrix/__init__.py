"""Repeated (one-stage, common-payoff) games: the random games of Section IV-C, classic
games and payoff files (:mod:`~.game`), their one-state compiled protocol
(:mod:`~.kernels`), a one-step ``ParallelEnv`` (:mod:`~.env`) and a text picture
(:mod:`~.render`)."""

from cmarlcd.games.matrix.env import MatrixGameEnv  # after game: it builds on it
from cmarlcd.games.matrix.game import (
    CASE2_OPTIMAL_FRACTION,
    KERNELS,
    MAX_JOINT_ACTIONS,
    OPTIMAL_PAYOFF,
    SUBOPTIMAL_SCALE,
    MatrixGame,
    case2_optimum_count,
    check_shape,
    check_size,
    climbing_game,
    from_payoffs,
    load_payoffs,
    penalty_game,
    random_case1,
    random_case2,
    random_game,
    validate_payoffs,
)
from cmarlcd.games.matrix.render import render_text

__all__ = [
    "CASE2_OPTIMAL_FRACTION",
    "KERNELS",
    "MAX_JOINT_ACTIONS",
    "OPTIMAL_PAYOFF",
    "SUBOPTIMAL_SCALE",
    "MatrixGame",
    "MatrixGameEnv",
    "case2_optimum_count",
    "check_shape",
    "check_size",
    "climbing_game",
    "from_payoffs",
    "load_payoffs",
    "penalty_game",
    "random_case1",
    "random_case2",
    "random_game",
    "render_text",
    "validate_payoffs",
]
