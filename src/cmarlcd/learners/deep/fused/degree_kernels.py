"""The fused CPU steps of deep CMARL-CD (``DeepCMARLCDConfig.step = "fused"``), gradients
derived by hand and Adam, seed by seed, in the layers of
:mod:`cmarlcd.learners.deep.fused.layers`.

The keyed update (:func:`keyed_step`): the regression of the degree networks onto the
keyed memory's degrees and of the record network onto its records. The maths is
:meth:`cmarlcd.learners.deep.degree_model.DegreeModel.keyed_loss`; for seed ``b`` with
``N`` kept states, degrees ``d_i(s) = W2ᵀ ReLU(W1ᵀ s + b1) + b2`` and the memory's
targets ``y_i``, records ``r``:
``L_b = Σ_t Σ_i Σ_a valid_ia (d_ia - y_ia)² / N  [+ Σ_t (R(s_t) - r_t)² / N]``,
so ``∂L/∂d_ia = 2 valid_ia (d_ia - y_ia) / N`` and ``∂L/∂R = 2 (R - r) / N``; the record
network ``R`` is a network of one output, differentiated the same way.

The shares (:func:`shares_step`; ``update="critic"``, ``critic_form="degrees"``): the
degrees at each visit's taken joint action summed, ``R_t = Σ_i d_i(s_t, a_t,i)``, fitted
to the visit's stored return ``G_t`` by the τ-expectile loss of
:meth:`~cmarlcd.learners.deep.degree_model.DegreeModel.expectile_loss`:
``L_b = Σ_t w_t (G_t - R_t)² / N`` with ``w_t = 1 - τ`` where ``G_t < R_t``, else ``τ``,
so ``∂L/∂d_i(s_t, a_t,i) = 2 w_t (R_t - G_t) / N`` for every agent ``i`` and 0 at the
actions not taken; the agent networks (one per agent or one shared, one hidden layer or
more) are those of VDN's fused step, :func:`~cmarlcd.learners.deep.fused.kernels.agents_forward`
and :func:`~cmarlcd.learners.deep.fused.kernels.agents_backward`.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.deep.fused.kernels import (
    agent_features,
    agents_backward,
    agents_forward,
    net_tables,
    net_tables_backward,
    network_backward_features,
    transposed,
)
from cmarlcd.learners.deep.fused.layers import fused, transpose_into, update_seed, zero_seed
from cmarlcd.learners.deep.fused.networks import gather_shared


@fused
def regress(net, grads, g: int, x, states, index: bool, target, valid, scratch) -> float:
    """One network of group ``g`` regressed onto ``target`` (N, A) over the ``valid``
    (A,) outputs: its squared error summed over the outputs and averaged over the
    transitions, with its gradients accumulated into ``grads``' group ``g``."""
    w1, b1, w2, b2 = net
    hidden, out, grad_hidden, grad_out, w2t, grad_w2t = scratch
    parts = (grads[0][g], grads[1][g], grads[2][g], grads[3][g])
    count, width = target.shape
    if index:
        net_tables(w1[g], b1[g], transposed(w2[g], w2t), b2[g], hidden, out)
        grad_out[:] = 0.0
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
            value = out[states[t], a] if index else out[a, t]
            error = value - target[t, a]
            loss += error * error / count
            if index:
                grad_out[states[t], a] += scale * error
            else:
                grad_out[a, t] = scale * error
    if index:
        net_tables_backward(w2t, hidden, grad_out, grad_hidden, grad_w2t, parts)
    else:
        network_backward_features(w2[g], x, hidden, grad_out, grad_hidden, parts)
    return loss


@fused
def scratch_for(units: int, width: int, index: bool, size: int) -> tuple:
    """A network's work arrays: hidden units, outputs and their gradients, over ``size``
    transitions feature-major (H, N), (A, N), or over ``size`` states state-major (S, H),
    (S, A); and W2 transposed with its gradient (A, H), for the states' tables."""
    if index:
        hidden, out = np.empty((size, units), np.float32), np.empty((size, width), np.float32)
    else:
        hidden, out = np.empty((units, size), np.float32), np.empty((width, size), np.float32)
    return (
        hidden,
        out,
        np.empty_like(hidden),
        np.empty_like(out),
        np.empty((width, units), np.float32),
        np.empty((width, units), np.float32),
    )


@fused
def keyed_step(nets, grads, batch, valid, shape, optimiser) -> float:
    """One step of deep CMARL-CD's keyed update for every seed: the summed losses, their
    gradients left in ``grads`` and Adam's update, seed by seed.

    ``nets``: (degree networks, record network), each (w1, b1, w2, b2) B*n- or B-stacked as
    the PyTorch modules hold them; ``grads`` likewise. ``batch``: (state features (B, N, F)
    or integer states (B, N), the memory's degrees (B, N, n, A), its records (B, N)).
    ``valid`` (n, A): each agent's real actions. ``shape``: (index: integer states, the
    number of states, estimates: whether the record network is fitted, each agent's
    first feature (n,) and ``own``: the features of each agent's own observation, its
    degree network's inputs, or 0 where it reads them all; the record network reads
    them all).
    ``optimiser``: as :func:`cmarlcd.learners.deep.fused.layers.update_seed` reads it.
    """
    agents, record = nets
    agent_grads, record_grads = grads
    features, states, target, records = batch
    index, n_states, estimates, starts, own = shape
    seeds, count, n, width = target.shape
    size = n_states if index else count
    inputs = 0 if index else features.shape[2]
    agent_scratch = scratch_for(agents[0].shape[2], width, index, size)
    record_scratch = scratch_for(record[0].shape[2], 1, index, size)
    x = np.empty((inputs, count), np.float32)
    record_target = np.empty((count, 1), np.float32)
    record_valid = np.ones(1, np.bool_)
    loss = 0.0
    for b in range(seeds):
        if not index:
            transpose_into(features[b], x)
        zero_seed(optimiser[1], b, seeds)
        for i in range(n):
            if own:  # its own observation: rows of the transposed features
                xi = x[starts[i] : starts[i] + own]
                loss += regress(
                    agents, agent_grads, b * n + i, xi, states[b], index, target[b, :, i],
                    valid[i], agent_scratch,
                )  # fmt: skip
            else:
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


@fused
def shares_step(agents, grads, batch, valid, shape, optimiser, shared) -> float:
    """One step of the shares for every seed (the module's maths): the summed losses,
    their gradients and Adam's update, seed by seed.

    ``agents``: the per-agent layers (B*n groups, as
    :func:`~cmarlcd.learners.deep.fused.kernels.td_step` takes them), ``grads`` likewise.
    ``batch``: (state features (B, N, F) or integer states (B, N), the taken joint actions
    (B, N, n), the stored returns (B, N)). ``valid`` (n, A): each agent's real actions.
    ``shape``: (index: integer states, ``own``: the features of each agent's own
    observation, the last ``n * own`` features, or 0 where it reads them all, τ).
    ``optimiser``: as :func:`cmarlcd.learners.deep.fused.layers.update_seed` reads it.
    ``shared``: (whether the agents share one network, its gradients), as ``td_step``'s.
    """
    features, states, actions, returns = batch
    index, own, tau = shape
    seeds, count, n = actions.shape
    width = agents[2].shape[2]
    units, layers = agents[0].shape[2], agents[4].shape[0] + 1
    if index:  # state-major tables (S, H) of the one hidden layer
        hidden = np.empty((n, 1, agents[0].shape[1], units), np.float32)
        x = np.empty((0, count), np.float32)
    else:
        hidden = np.empty((n, layers, units, count), np.float32)
        x = np.empty((features.shape[2], count), np.float32)
    no_masks = np.empty((0, 0, n, width), np.bool_)
    legal_of = (False, no_masks, no_masks)
    c = np.empty((n, count), np.float32)
    best = np.empty((n, 0), np.float32)
    grad_c = np.empty((n, count), np.float32)
    above, below = np.float32(tau), np.float32(1.0 - tau)
    loss = 0.0
    for b in range(seeds):
        if not index:
            transpose_into(features[b], x)
        inputs = (index, x, x, states[b], states[b], actions[b], legal_of, own)
        agents_forward(agents, agents, b, inputs, c, best, hidden, valid, False, False)
        for t in range(count):
            total = np.float32(0.0)
            for i in range(n):
                total += c[i, t]
            error = total - returns[b, t]
            weight = below if returns[b, t] < total else above
            loss += weight * error * error / count
            slope = np.float32(2.0) * weight * error / np.float32(count)
            for i in range(n):
                grad_c[i, t] = slope
        zero_seed(optimiser[1], b, seeds)
        agents_backward(agents, grads, b, inputs, grad_c, hidden)
        if shared[0]:
            gather_shared(grads, shared[1], b, n)
        update_seed(optimiser, b, seeds)
    return loss
