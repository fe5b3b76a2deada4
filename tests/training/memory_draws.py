"""What the behaviour tests of deep CMARL-CD share: joint actions drawn by the compiled
loop at CHAIN's state 2, whose keyed memory holds degrees set by hand."""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.testing import CHAIN

#: Acting from the memory's degrees at CHAIN's state 2, which the tests set by hand.
MEMORY = {"act_from": "memory", "unseen_record": "first-visit", "buffer_size": 64,
          "batch_size": 8, "train_every": 4}  # fmt: skip


def draws_at_state_2(
    config: DeepCMARLCDConfig, best: float, times: int, turns: int = 0
) -> list[tuple[int, int]]:
    """``times`` joint actions drawn at CHAIN's state 2 after ``turns`` steps, whose
    memory holds degrees (0.5, best, 0.5) for agent 0 and (0.5, 0.5, best) for agent 1
    (``config`` acts from the memory: :data:`MEMORY`), with generator seed 0."""
    from cmarlcd.training.deep import DeepBatch
    from cmarlcd.training.deep_kernels import TURNS

    batch = DeepBatch(CHAIN, config, [np.random.SeedSequence(3)], 300)
    view = batch.group.views[0]
    data, memory = view.data, view.data.replay.memory
    memory.filled[2], memory.key[2] = True, np.uint64(2)
    memory.target[2] = [[0.5, best, 0.5], [0.5, 0.5, best]]
    data.counters[TURNS] = turns
    rng, joint = np.random.default_rng(0), np.zeros(2, np.int64)
    out = []
    for _ in range(times):
        view.kernels.act(data, 2, rng, joint)
        out.append((int(joint[0]), int(joint[1])))
    return out
