"""The fused CPU step of deep CMARL-CD's keyed update (``DeepCMARLCDConfig.step =
"fused"``): the regression of the degree networks onto the keyed memory's degrees and of
the record network onto its records, gradients derived by hand and Adam, seed by seed, in
the layers of :mod:`cmarlcd.learners.fused_layers`.

The maths is :meth:`cmarlcd.learners.degree_model.DegreeModel.keyed_loss`; for seed ``b``
with ``N`` kept states, degrees ``d_i(s) = W2ᵀ ReLU(W1ᵀ s + b1) + b2`` and the memory's
targets ``y_i``, records ``r``:
``L_b = Σ_t Σ_i Σ_a valid_ia (d_ia - y_ia)² / N  [+ Σ_t (R(s_t) - r_t)² / N]``,
so ``∂L/∂d_ia = 2 valid_ia (d_ia - y_ia) / N`` and ``∂L/∂R = 2 (R - r) / N``; the record
network ``R`` is a network of one output, differentiated the same way.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.fused_kernels import (
    agent_features,
    agent_tables,
    network_backward_features,
    network_backward_tables,
)
from cmarlcd.learners.fused_layers import fused, transpose_into, update_seed, zero_seed


@fused
def regress(net, grads, g: int, x, states, index: bool, target, valid, scratch) -> float:
    """One network of group ``g`` regressed onto ``target`` (N, A) over the ``valid``
    (A,) outputs: its squared error summed over the outputs and averaged over the
    transitions, with its gradients accumulated into ``grads``' group ``g``."""
    w1, b1, w2, b2 = net
    hidden, out, grad_hidden, grad_out, table_grad = scratch
    parts = (grads[0][g], grads[1][g], grads[2][g], grads[3][g])
    count, width = target.shape
    if index:
        agent_tables(w1[g], b1[g], w2[g], b2[g], hidden, out)
        table_grad[:] = 0.0
    else:
        agent_features(w1[g], b1[g], w2[g], b2[g], x, hidden, out)
    loss = 0.0
    scale = np.float32(2.0 / count)
    for a in range(width):
        if not valid[a]:
            if not index:
                grad_out[a] = 0.0
            continue
        for t in range(count):
            value = out[a, states[t]] if index else out[a, t]
            error = value - target[t, a]
            loss += error * error / count
            if index:
                table_grad[a, states[t]] += scale * error
            else:
                grad_out[a, t] = scale * error
    if index:
        network_backward_tables(w2[g], hidden, table_grad, grad_hidden, parts)
    else:
        network_backward_features(w2[g], x, hidden, grad_out, grad_hidden, parts)
    return loss


@fused
def scratch_for(units: int, width: int, columns: int, count: int, table: int) -> tuple:
    """A network's work arrays: hidden, outputs, their gradients (feature-major over the
    ``columns``: the batch, or the states) and a per-state gradient table."""
    return (
        np.empty((units, columns), np.float32),
        np.empty((width, columns), np.float32),
        np.empty((units, columns), np.float32),
        np.empty((width, count), np.float32),
        np.zeros((width, table), np.float32),
    )


@fused
def keyed_step(nets, grads, batch, valid, shape, optimiser) -> float:
    """One step of deep CMARL-CD's keyed update for every seed: the summed losses, their
    gradients left in ``grads`` and Adam's update, seed by seed.

    ``nets``: (degree networks, record network), each (w1, b1, w2, b2) B*n- or B-stacked as
    the PyTorch modules hold them; ``grads`` likewise. ``batch``: (state features (B, N, F)
    or integer states (B, N), the memory's degrees (B, N, n, A), its records (B, N)).
    ``valid`` (n, A): each agent's real actions. ``shape``: (index: integer states, the
    number of states, estimates: whether the record network is fitted).
    ``optimiser``: as :func:`cmarlcd.learners.fused_layers.update_seed` reads it.
    """
    agents, record = nets
    agent_grads, record_grads = grads
    features, states, target, records = batch
    index, n_states, estimates = shape
    seeds, count, n, width = target.shape
    columns = n_states if index else count
    inputs = 0 if index else features.shape[2]
    table = n_states if index else 0
    agent_scratch = scratch_for(agents[0].shape[2], width, columns, count, table)
    record_scratch = scratch_for(record[0].shape[2], 1, columns, count, table)
    x = np.empty((inputs, count), np.float32)
    record_target = np.empty((count, 1), np.float32)
    record_valid = np.ones(1, np.bool_)
    loss = 0.0
    for b in range(seeds):
        if not index:
            transpose_into(features[b], x)
        zero_seed(optimiser[1], b, seeds)
        for i in range(n):
            loss += regress(
                agents, agent_grads, b * n + i, x, states[b], index, target[b, :, i],
                valid[i], agent_scratch,
            )  # fmt: skip
        if estimates:
            record_target[:, 0] = records[b]
            loss += regress(
                record, record_grads, b, x, states[b], index, record_target, record_valid,
                record_scratch,
            )  # fmt: skip
        update_seed(optimiser, b, seeds)
    return loss
