"""The values the paper publishes, for side-by-side reports.

Transcribed from the paper's tables; never used by any learner.
"""

from __future__ import annotations

#: The agents n and actions m of the cells of Table 1 (case 1) and Table 2 (case 2).
TABLE_AGENTS = {1: (2, 3, 4, 5, 6, 7), 2: (4, 5, 6, 7)}
TABLE_ACTIONS = {1: (2, 3, 4, 5), 2: (3, 4, 5)}

#: Table 1 (case 1): success rate 100 % in every cell except n = 7 agents, m = 4 actions.
_TABLE1_EXCEPTIONS = {(7, 4): 0.98}
_TABLE1_AGENTS = range(2, 8)
_TABLE1_ACTIONS = range(2, 6)
#: Table 2 (case 2): success rate 100 % in every cell.
_TABLE2_AGENTS = range(4, 8)
_TABLE2_ACTIONS = range(3, 6)


def repeated_success(case: int, agents: int, actions: int) -> float | None:
    """The paper's success rate for a cell of Table 1 (case 1) or 2 (case 2), else None."""
    if case == 1 and agents in _TABLE1_AGENTS and actions in _TABLE1_ACTIONS:
        return _TABLE1_EXCEPTIONS.get((agents, actions), 1.0)
    if case == 2 and agents in _TABLE2_AGENTS and actions in _TABLE2_ACTIONS:
        return 1.0
    return None


#: Tables 3-7 (DSN, Section V-A): per algorithm, per L = 100k / 300k / 500k episodes.
#: Keys of each row: success (Table 3), return mean | std (Table 4), steps mean | std
#: (Table 5), min_return (Table 6), max_steps (Table 7).
DSN_EPISODES = (100_000, 300_000, 500_000)
_DSN = {
    "cmarl-cd": {
        "success_rate": (0.9090, 1.0, 1.0),
        "mean_return": (41.90, 42.0, 42.0),
        "std_return": (0.10, 0.0, 0.0),
        "mean_steps": (3.06, 3.0, 3.0),
        "std_steps": (0.07, 0.0, 0.0),
        "min_return": (41.60, 42.0, 42.0),
        "max_steps": (3.20, 3.0, 3.0),
    },
    "la-oca": {
        "success_rate": (0.4657, 0.8916, 0.9508),
        "mean_return": (39.92, 41.63, 41.80),
        "std_return": (0.72, 0.42, 0.30),
        "mean_steps": (3.39, 3.11, 3.05),
        "std_steps": (0.15, 0.10, 0.07),
        "min_return": (38.00, 40.11, 40.66),
        "max_steps": (3.68, 3.33, 3.23),
    },
    "vdn": {
        "success_rate": (0.0040, 0.0549, 0.0785),
        "mean_return": (36.75, 39.51, 40.63),
        "std_return": (0.78, 0.98, 0.57),
        "mean_steps": (6.48, 5.29, 5.09),
        "std_steps": (0.25, 0.10, 0.10),
        "min_return": (35.98, 37.35, 39.23),
        "max_steps": (7.39, 5.60, 5.33),
    },
    "qmix": {
        "success_rate": (0.0329, 0.0688, 0.0642),
        "mean_return": (39.49, 40.81, 41.17),
        "std_return": (1.05, 0.70, 0.44),
        "mean_steps": (6.30, 5.09, 5.07),
        "std_steps": (0.49, 0.12, 0.10),
        "min_return": (37.60, 38.52, 40.01),
        "max_steps": (7.74, 5.37, 5.25),
    },
}


def dsn_value(algorithm: str, episodes: int, metric: str) -> float | None:
    """The paper's value of ``metric`` for ``algorithm`` after ``episodes`` (None if absent)."""
    row = _DSN.get(algorithm, {}).get(metric)
    if row is None or episodes not in DSN_EPISODES:
        return None
    return row[DSN_EPISODES.index(episodes)]


#: The paper's algorithms in the order of Table 3.
DSN_ALGORITHMS = tuple(_DSN)
