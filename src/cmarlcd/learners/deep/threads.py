"""How many intra-op threads a deep learner's gradient step takes (``[deep]`` extra).

torch runs each operation on as many threads as the process allows (by default every
core), which pays where the operation is large and costs where it is small: a stacked
model of one seed steps on a few hundred kilobytes, and waking a pool of threads for each
of its operations takes longer than the operation (measured on a 16-core machine: the
battlefield's VDN against QMIX, one round, 158 learning turns a second with 16 threads
where a 2-core machine runs 9,483 with its 2). So each model chooses, once, the threads
of its steps from their work and the threads the process allows
(:func:`step_threads`), and steps with them (:func:`intra_op_threads`); everything else
in the process keeps its own setting.

The fused step (:mod:`cmarlcd.learners.deep.fused`) is compiled numba code that torch's
threads do not run, and on a GPU the card does the work: both take one.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch

#: [choice] The multiply-adds of a step's forward pass each intra-op thread must have for
#: one more thread to pay (:func:`step_threads`): read off ``benchmarks/bench_threads.py``
#: (docs: Benchmarks, threads of a gradient step).
WORK_PER_THREAD = 20_000_000


def step_work(model) -> int:
    """The multiply-adds of one forward pass of ``model`` (a stacked model) over a replay
    batch: every seed's batch through its online networks, each weight (of the stacked
    layers' (groups, in, out) matrices) used once a sample; for one-hot inputs, which read
    one row of the first layer a sample, a bound from above."""
    weights = sum(p.numel() for p in model.parameters() if p.requires_grad and p.dim() == 3)
    return int(weights * model.config.batch_size)


def step_threads(work: int, available: int) -> int:
    """Threads for a step of ``work`` multiply-adds when the process allows ``available``:
    one per :data:`WORK_PER_THREAD`, at least one and at most ``available``."""
    return max(1, min(int(available), int(work) // WORK_PER_THREAD))


@contextlib.contextmanager
def intra_op_threads(count: int) -> Iterator[None]:
    """torch's intra-op threads set to ``count`` inside the block (the setting before it
    restored after)."""
    before = torch.get_num_threads()
    if before != count:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        if before != count:
            torch.set_num_threads(before)
