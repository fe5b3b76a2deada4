"""The values the paper publishes, for side-by-side reports.

Transcribed from the paper's tables (see SPEC.md); never used by any learner.
"""

from __future__ import annotations

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
