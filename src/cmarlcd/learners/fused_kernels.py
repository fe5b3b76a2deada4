"""Compiled kernels of the fused CPU step of VDN and QMIX: forward, hand-derived backward
and Adam in one pass per seed, with no per-operation overhead (no PyTorch here).

Why: the autograd step of the stacked small networks spends its time in per-operation
overhead and in element-wise passes over large intermediates, not in arithmetic
(:mod:`benchmarks.bench_fused_step` measures both). These kernels take each seed in turn,
keep its intermediates small, and lay every one out *feature-major*: an array ``(units,
N)`` whose rows run over the batch, so that every inner loop is a long contiguous loop
over the batch's transitions, which the compiler vectorises.

The maths is :meth:`cmarlcd.learners.value_decomposition.ValueDecomposition.td_loss`
(paper Section V-A/B) differentiated by hand; for one seed ``b`` with ``N`` transitions:

* agents: ``z = W1ᵀx + b1``, ``h = ReLU(z)``, ``Q = W2ᵀh + b2``, ``c_i = Q_i[a_i]``;
* VDN: ``Q_tot = Σ_i c_i``; QMIX: ``Q_tot = Σ_k ELU(Σ_i c_i |W1(s)|_ik + B1(s)_k)
  |W2(s)|_k + V(s)`` with hypernetworks ``W1, B1, W2`` and ``V(s) = v2ᵀ ReLU(V1(s)) +
  v2_b``;
* target ``y = r + γ (1 - terminal) Q_tot'(s', argmax-legal Q'_i)`` from the target
  networks, loss ``L_b = Σ_t (Q_tot - y)² / N`` (the step's loss is ``Σ_b L_b``);
* ``∂L/∂Q_tot = 2 (Q_tot - y) / N``; through ``|·|`` the gradient is multiplied by
  ``sign`` (0 at 0), through ReLU by ``[out > 0]``, through ELU by ``exp(x)`` for
  ``x <= 0``, as PyTorch's backward functions do.

Integer (one-hot) inputs read rows: the agent networks are evaluated once per state, as
tables, and the mixer's layers at each transition's state row; their gradients are the
rows' sums.

Compiled with ``fastmath`` reassociation and contraction only (never ``nnan``/``ninf``:
illegal actions are ``-inf``), so sums are taken in another order than PyTorch's: the
results equal the autograd step's to float32 rounding, not bit for bit.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.fused_layers import (
    dense_backward,
    dense_forward,
    fused,
    layer_backward,
    layer_forward,
    relu_inplace,
    transpose_into,
    update_seed,
    zero_seed,
)

# ------------------------------------------------------------------ agent networks


@fused
def agent_features(w1, b1, w2, b2, x, hidden, q) -> None:
    """One agent network on feature inputs ``x`` (F, N): ``hidden`` := ReLU(z) (H, N),
    ``q`` := its Q-values (A, N)."""
    dense_forward(w1, b1, x, hidden)
    relu_inplace(hidden)
    dense_forward(w2, b2, hidden, q)


@fused
def agent_tables(w1, b1, w2, b2, hidden, q) -> None:
    """One agent network at every one-hot state, feature-major: ``hidden`` := ReLU(W1ᵀ +
    b1) (H, S), ``q`` := its Q-values (A, S)."""
    for s in range(w1.shape[0]):
        for h in range(w1.shape[1]):
            z = w1[s, h] + b1[h]
            hidden[h, s] = z if z > 0.0 else 0.0
    dense_forward(w2, b2, hidden, q)


@fused
def best_legal(q, legal, valid, out) -> None:
    """``out[t]`` := max over legal and valid actions ``a`` of ``q[a, t]`` (-inf if none)."""
    for t in range(out.shape[0]):
        best = -np.inf
        for a in range(q.shape[0]):
            if legal[t, a] and valid[a] and q[a, t] > best:
                best = q[a, t]
        out[t] = best


@fused
def agent_backward_features(w2, x, hidden, actions, grad_c, grad_q, grad_hidden, grads) -> None:
    """Gradients of one agent network on feature inputs, from ``grad_c`` (N,), the loss's
    gradient with respect to the Q-value of each transition's action."""
    gw1, gb1, gw2, gb2 = grads
    grad_q[:] = 0.0
    for t in range(actions.shape[0]):
        grad_q[actions[t], t] = grad_c[t]
    dense_backward(hidden, grad_q, gw2, gb2)
    for h in range(hidden.shape[0]):  # ∂L/∂h = W2[:, a_t] ∂L/∂c, through ReLU
        row, out = hidden[h], grad_hidden[h]
        for t in range(actions.shape[0]):
            out[t] = w2[h, actions[t]] * grad_c[t] if row[t] > 0.0 else 0.0
    dense_backward(x, grad_hidden, gw1, gb1)


@fused
def hidden_gradient(w2, hidden, grad_q, grad_hidden) -> None:
    """``grad_hidden`` (H, M) := ``W2 grad_q`` through the ReLU of ``hidden`` (H, M)."""
    for h in range(hidden.shape[0]):
        row, out = hidden[h], grad_hidden[h]
        out[:] = 0.0
        for a in range(grad_q.shape[0]):
            w, d = w2[h, a], grad_q[a]
            for m in range(row.shape[0]):
                out[m] += w * d[m]
        for m in range(row.shape[0]):
            if not row[m] > 0.0:
                out[m] = 0.0


@fused
def network_backward_features(w2, x, hidden, grad_q, grad_hidden, grads) -> None:
    """Gradients of one network on feature inputs ``x`` (F, N) from ``grad_q`` (A, N),
    the loss's gradient with respect to every output."""
    gw1, gb1, gw2, gb2 = grads
    dense_backward(hidden, grad_q, gw2, gb2)
    hidden_gradient(w2, hidden, grad_q, grad_hidden)
    dense_backward(x, grad_hidden, gw1, gb1)


@fused
def network_backward_tables(w2, hidden, grad_q, grad_hidden, grads) -> None:
    """Gradients of one network on one-hot inputs from ``grad_q`` (A, S), each state's
    gradient with respect to every output: the first layer's rows are the states."""
    gw1, gb1, gw2, gb2 = grads
    dense_backward(hidden, grad_q, gw2, gb2)
    hidden_gradient(w2, hidden, grad_q, grad_hidden)
    for h in range(hidden.shape[0]):
        out, total = grad_hidden[h], np.float32(0.0)
        for s in range(out.shape[0]):
            gw1[s, h] += out[s]
            total += out[s]
        gb1[h] += total


@fused
def agent_backward_tables(w2, hidden, states, actions, grad_c, grad_q, grad_hidden, grads) -> None:
    """Gradients of one agent network on one-hot inputs: ``grad_q`` (A, S) gathers each
    state's ``∂L/∂Q`` of the transitions' actions."""
    grad_q[:] = 0.0
    for t in range(states.shape[0]):
        grad_q[actions[t], states[t]] += grad_c[t]
    network_backward_tables(w2, hidden, grad_q, grad_hidden, grads)


# ------------------------------------------------------------------ mixers


@fused
def qmix_forward(mixer, b: int, c, x, states, index: bool, scratch, q_tot) -> None:
    """QMIX's ``Q_tot`` (N,) of seed ``b`` for the agents' values ``c`` (n, N) at its
    states (``x`` (S, N) features or ``states`` (N,) indices). ``scratch`` keeps, for the
    backward pass: W1(s) (n*K, N), B1(s)+Σ (pre-activation) and ELU (K, N) each, W2(s),
    ReLU(V1(s)) (K, N)."""
    hw1, hw1_b, hb1, hb1_b, hw2, hw2_b, v1, v1_b, v2, v2_b = mixer
    w1s, pre, hid, w2s, val = scratch
    n, count = c.shape
    k_units = pre.shape[0]
    layer_forward(hw1[b], hw1_b[b], x, states, index, w1s)
    layer_forward(hb1[b], hb1_b[b], x, states, index, pre)
    layer_forward(hw2[b], hw2_b[b], x, states, index, w2s)
    layer_forward(v1[b], v1_b[b], x, states, index, val)
    relu_inplace(val)
    for t in range(count):
        q_tot[t] = v2_b[b, 0]
    for k in range(k_units):
        p, e, w, v = pre[k], hid[k], w2s[k], val[k]
        for i in range(n):
            wi, ci = w1s[i * k_units + k], c[i]
            for t in range(count):
                p[t] += ci[t] * abs(wi[t])
        weight = v2[b, k, 0]
        for t in range(count):
            e[t] = p[t] if p[t] > 0.0 else np.expm1(p[t])
            q_tot[t] += e[t] * abs(w[t]) + v[t] * weight


@fused
def qmix_backward(mixer, grads, b: int, c, x, states, index: bool, scratch, grad, grad_c) -> None:
    """Gradients of :func:`qmix_forward` for ``grad`` = ∂L/∂Q_tot (N,): into the mixer's
    ``grads`` (seed ``b``'s rows) and ``grad_c`` (n, N), ∂L/∂c. Overwrites ``scratch``."""
    v2 = mixer[8]
    g_hw1, g_hw1_b, g_hb1, g_hb1_b, g_hw2, g_hw2_b, g_v1, g_v1_b, g_v2, g_v2_b = grads
    w1s, pre, hid, w2s, val = scratch
    n, count = c.shape
    k_units = pre.shape[0]
    grad_c[:] = 0.0
    total_grad = np.float32(0.0)
    for t in range(count):
        total_grad += grad[t]
    g_v2_b[b, 0] += total_grad
    for k in range(k_units):
        p, e, w, v = pre[k], hid[k], w2s[k], val[k]
        weight = v2[b, k, 0]
        total = np.float32(0.0)
        for t in range(count):
            total += v[t] * grad[t]
            v_out = grad[t] * weight if v[t] > 0.0 else 0.0  # ∂L/∂V1(s), through ReLU
            d_hid = grad[t] * abs(w[t])
            d_w2 = grad[t] * e[t]
            w[t] = d_w2 if w[t] > 0.0 else (-d_w2 if w[t] < 0.0 else 0.0)  # through |·|
            p[t] = d_hid if p[t] > 0.0 else d_hid * np.exp(p[t])  # through ELU
            v[t] = v_out
        g_v2[b, k, 0] += total
        for i in range(n):  # ∂L/∂c_i and ∂L/∂W1(s)_ik, through |·|
            wi, ci, gi = w1s[i * k_units + k], c[i], grad_c[i]
            for t in range(count):
                gi[t] += p[t] * abs(wi[t])
                d = p[t] * ci[t]
                wi[t] = d if wi[t] > 0.0 else (-d if wi[t] < 0.0 else 0.0)
    layer_backward(x, states, index, w1s, g_hw1[b], g_hw1_b[b])
    layer_backward(x, states, index, pre, g_hb1[b], g_hb1_b[b])
    layer_backward(x, states, index, w2s, g_hw2[b], g_hw2_b[b])
    layer_backward(x, states, index, val, g_v1[b], g_v1_b[b])


@fused
def mix(qmix: bool, mixer, b, c, x, states, index, scratch, q_tot) -> None:
    """``Q_tot`` of seed ``b``: QMIX's mixer, or VDN's sum."""
    if qmix:
        qmix_forward(mixer, b, c, x, states, index, scratch, q_tot)
        return
    q_tot[:] = 0.0
    for i in range(c.shape[0]):
        for t in range(c.shape[1]):
            q_tot[t] += c[i, t]


# ------------------------------------------------------------------ the step


@fused
def agents_forward(agents, target_agents, b, inputs, c, best, hidden, kept) -> None:
    """Every agent of seed ``b``: ``c`` (n, N) the online Q of each transition's action
    (``hidden`` keeps what the backward pass reads), ``best`` (n, N) the target networks'
    best legal Q at the next state. ``inputs``: see :func:`td_step`."""
    w1, b1, w2, b2 = agents
    tw1, tb1, tw2, tb2 = target_agents
    index, x, nx, states, next_states, actions, legal_of, own_dim = inputs
    n, count = c.shape
    width = w2.shape[2]
    q = np.empty((width, count), np.float32)
    legal = np.empty((count, width), np.bool_)
    target_hidden = np.empty_like(hidden[0])
    tables = np.empty((width, w1.shape[1]), np.float32)
    for i in range(n):
        g = b * n + i
        legal_of_agent(legal_of, b, i, next_states, legal)
        if index:
            agent_tables(w1[g], b1[g], w2[g], b2[g], hidden[i], tables)
            for t in range(count):
                c[i, t] = tables[actions[t, i], states[t]]
            agent_tables(tw1[g], tb1[g], tw2[g], tb2[g], target_hidden, tables)
            for a in range(width):
                for t in range(count):
                    q[a, t] = tables[a, next_states[t]]
        else:
            lo = 0 if own_dim == 0 else x.shape[0] - (n - i) * own_dim
            hi = x.shape[0] if own_dim == 0 else lo + own_dim
            agent_features(w1[g], b1[g], w2[g], b2[g], x[lo:hi], hidden[i], q)
            for t in range(count):
                c[i, t] = q[actions[t, i], t]
            agent_features(tw1[g], tb1[g], tw2[g], tb2[g], nx[lo:hi], target_hidden, q)
        best_legal(q, legal, kept[i], best[i])


@fused
def legal_of_agent(legal_of, b, i, next_states, out) -> None:
    """Agent ``i``'s legal actions at each next state (N, A): the batch's own masks, the
    per-state masks of integer states, or every action."""
    per_sample, next_legal, state_legal = legal_of
    if per_sample:
        out[:] = next_legal[b, :, i, :]
    elif state_legal.shape[0]:
        for t in range(out.shape[0]):
            out[t] = state_legal[b, next_states[t], i]
    else:
        out[:] = True


@fused
def agents_backward(agents, grads, b, inputs, grad_c, hidden) -> None:
    """Every agent of seed ``b``: gradients from ``grad_c`` (n, N), ∂L/∂c."""
    w1, w2 = agents[0], agents[2]
    gw1, gb1, gw2, gb2 = grads
    index, x, states, actions, own_dim = inputs[0], inputs[1], inputs[3], inputs[5], inputs[7]
    n, count = grad_c.shape
    grad_hidden = np.empty_like(hidden[0])
    if index:
        grad_q = np.empty((w2.shape[2], w1.shape[1]), np.float32)
    else:
        grad_q = np.empty((w2.shape[2], count), np.float32)
    for i in range(n):
        g = b * n + i
        parts = (gw1[g], gb1[g], gw2[g], gb2[g])
        if index:
            agent_backward_tables(
                w2[g], hidden[i], states, actions[:, i], grad_c[i], grad_q, grad_hidden, parts
            )
        else:
            lo = 0 if own_dim == 0 else x.shape[0] - (n - i) * own_dim
            hi = x.shape[0] if own_dim == 0 else lo + own_dim
            agent_backward_features(
                w2[g], x[lo:hi], hidden[i], actions[:, i], grad_c[i], grad_q, grad_hidden, parts
            )


@fused
def td_step(nets, grads, batch, legal_of, valid, shape, optimiser) -> float:
    """One step: the summed TD losses of every seed (paper Section V-A/B), their
    gradients left in ``grads``, and Adam's update of every parameter, seed by seed.

    ``nets``: (agents, target agents, mixer, target mixer), each a tuple of B-stacked
    arrays as the PyTorch modules hold them (agents seed-major, B*n groups); ``grads``:
    (agents', mixer's). ``batch``: (state features (B, N, D) or integer states (B, N),
    their next states likewise, actions (B, N, n), reward, terminal (B, N)); ``legal_of``:
    (whether the batch has its own masks, them (B, N, n, A), per-state masks (B, S, n, A)
    or empty); ``valid`` (n, A): each agent's real actions. ``shape``: (qmix, index,
    discount, own_dim: features of each agent's own observation or 0, mixer_dim: the
    leading features the mixer reads, mixer hidden units). ``optimiser``: the flat
    parameters, gradients (the same memory as ``grads``) and Adam's two moments, and
    Adam's settings (:func:`adam`).
    """
    agents, target_agents, mixer, target_mixer = nets
    agent_grads, mixer_grads = grads
    features, next_features, states, next_states, actions, reward, terminal = batch
    qmix, index, gamma, own_dim, mixer_dim, units = shape
    seeds, count, n = actions.shape
    hidden_units = agents[0].shape[2]
    if index:
        hidden = np.empty((n, hidden_units, agents[0].shape[1]), np.float32)
        x = np.empty((0, count), np.float32)
        nx = np.empty((0, count), np.float32)
    else:
        hidden = np.empty((n, hidden_units, count), np.float32)
        x = np.empty((features.shape[2], count), np.float32)
        nx = np.empty((features.shape[2], count), np.float32)
    c = np.empty((n, count), np.float32)
    best = np.empty((n, count), np.float32)
    grad_c = np.empty((n, count), np.float32)
    q_tot = np.empty(count, np.float32)
    next_tot = np.empty(count, np.float32)
    grad = np.empty(count, np.float32)
    scratch = (
        np.empty((n * units, count), np.float32),
        np.empty((units, count), np.float32),
        np.empty((units, count), np.float32),
        np.empty((units, count), np.float32),
        np.empty((units, count), np.float32),
    )
    loss = 0.0
    discount = np.float32(gamma)
    for b in range(seeds):
        if not index:
            transpose_into(features[b], x)
            transpose_into(next_features[b], nx)
        inputs = (index, x, nx, states[b], next_states[b], actions[b], legal_of, own_dim)
        agents_forward(agents, target_agents, b, inputs, c, best, hidden, valid)
        mixed, next_mixed = x[:mixer_dim], nx[:mixer_dim]
        mix(qmix, target_mixer, b, best, next_mixed, next_states[b], index, scratch, next_tot)
        mix(qmix, mixer, b, c, mixed, states[b], index, scratch, q_tot)
        for t in range(count):
            alive = np.float32(0.0) if terminal[b, t] else np.float32(1.0)
            error = q_tot[t] - (reward[b, t] + discount * alive * next_tot[t])
            loss += error * error / count
            grad[t] = np.float32(2.0) * error / np.float32(count)
        zero_seed(optimiser[1], b, seeds)
        if qmix:
            qmix_backward(mixer, mixer_grads, b, c, mixed, states[b], index, scratch, grad, grad_c)
        else:
            for i in range(n):
                grad_c[i] = grad
        agents_backward(agents, agent_grads, b, inputs, grad_c, hidden)
        update_seed(optimiser, b, seeds)
    return loss
