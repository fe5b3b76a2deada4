"""The λ-return tests' hand episode, stored by the compiled loop: three visits at the one
feature x = 0, 1, 2 with rewards 1, 2, 4, γ 0.5 (the tests give λ and what the returns
bootstrap from); shared by the critic's, the shares' and the refresh's tests."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig

#: The hand episode's game: one feature, no state index, three steps.
SPEC = SimpleNamespace(n_states=0, own_dim=None, n_features=1, max_steps=3)


def degree_layers(agents: int, actions: int):
    """Zeroed degree (or critic) networks of ``agents`` agents on the one feature: four
    hidden units, ``actions`` outputs (the compiled loop's weights)."""
    from cmarlcd.training.deep_kernels import Weights

    shapes = ((1, 4), (4,), (4, actions), (actions,), (0, 4, 4), (0, 4))
    return Weights(*(np.zeros((agents, *shape), np.float32) for shape in shapes))


def store_hand_episode(
    replay, counts: np.ndarray, degrees, joints: list[list[int]], config=None
) -> None:
    """The compiled loop's λ-store of the hand episode into ``replay`` (a view of one
    seed's bootstrapped ring), the agents acting ``joints`` on their ``degrees``, under
    the schedule of ``config`` (the default's) at γ 0.5."""
    from cmarlcd.training.deep_kernels import FeatureData
    from cmarlcd.training.deep_side import new_greedy_cache
    from cmarlcd.training.degree_kernels import features_lambda_store

    agents, width = len(counts), int(max(counts))
    config = replace(config or DeepCMARLCDConfig(), gamma=0.5)
    schedule = np.array(config.schedule(100), np.float64)
    obs = np.array([[0.0], [1.0], [2.0], [0.0], [0.0]], np.float32)
    side = FeatureData(
        counts, degrees, np.zeros(8, np.float32), obs, np.ones((4, agents, width), np.bool_),
        np.array(joints), np.array([1.0, 2.0, 4.0]), replay, np.zeros(8, np.int64), schedule,
        np.zeros((2, width)),
        new_greedy_cache(SimpleNamespace(state_determines_features=False, max_steps=3), 1),
        np.zeros(agents, np.int64),
    )  # fmt: skip
    features_lambda_store(side, 3)
