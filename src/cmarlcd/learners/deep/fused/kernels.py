"""Compiled kernels of the fused CPU step of VDN and QMIX: forward, hand-derived backward
and Adam in one pass per seed, with no per-operation overhead (no PyTorch here).

Why: the autograd step of the stacked small networks spends its time in per-operation
overhead and in element-wise passes over large intermediates, not in arithmetic
(:mod:`benchmarks.bench_fused_step` measures both). These kernels take each seed in turn,
keep its intermediates small, and lay every one out *feature-major*: an array ``(units,
N)`` whose rows run over the batch, so that every inner loop is a long contiguous loop
over the batch's transitions, which the compiler vectorises.

The maths is :meth:`cmarlcd.learners.deep.value_decomposition.ValueDecomposition.td_loss`
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

from cmarlcd.learners.deep.fused.layers import (
    clip_seed,
    dense_backward,
    dense_forward,
    fused,
    relu_inplace,
    transpose_into,
    update_seed,
    zero_seed,
)
from cmarlcd.learners.deep.fused.mixers import mix, mix_backward, state_scratch
from cmarlcd.learners.deep.fused.networks import (
    gather_shared,
    network_backward,
    network_forward,
    through_relu,
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
def net_tables(w1, b1, w2t, b2, hidden, q) -> None:
    """One network at every one-hot state, state-major: ``hidden`` := ReLU(W1 + b1)
    (S, H), ``q`` := its outputs (S, A); ``w2t`` (A, H) is W2 transposed, so that every
    inner loop runs over the H hidden units of a contiguous row. (Two-dimensional indices,
    not row views: a view made in a loop costs two atomic reference counts.)"""
    units = hidden.shape[1]
    for s in range(w1.shape[0]):
        for h in range(units):
            v = w1[s, h] + b1[h]
            hidden[s, h] = v if v > 0.0 else 0.0
        for a in range(w2t.shape[0]):
            total = b2[a]
            for h in range(units):
                total += hidden[s, h] * w2t[a, h]
            q[s, a] = total


@fused
def net_tables_backward(w2t, hidden, grad_q, grad_hidden, grad_w2t, grads) -> None:
    """Gradients of :func:`net_tables` from ``grad_q`` (S, A), each state's gradient with
    respect to every output (zeros are skipped: a batch reaches few state-action pairs).
    ``grad_w2t`` (A, H) is scratch."""
    gw1, gb1, gw2, gb2 = grads
    units = hidden.shape[1]
    grad_w2t[:] = 0.0
    for s in range(hidden.shape[0]):
        for h in range(units):
            grad_hidden[s, h] = 0.0
        for a in range(w2t.shape[0]):
            d = grad_q[s, a]
            if d != 0.0:
                gb2[a] += d
                for h in range(units):
                    grad_hidden[s, h] += d * w2t[a, h]
                    grad_w2t[a, h] += d * hidden[s, h]
        for h in range(units):
            v = grad_hidden[s, h] if hidden[s, h] > 0.0 else np.float32(0.0)
            gw1[s, h] += v
            gb1[h] += v
    for a in range(w2t.shape[0]):
        for h in range(units):
            gw2[h, a] += grad_w2t[a, h]


@fused
def transposed(w, out):
    """``out`` := ``w`` (H, A) transposed (A, H); returns ``out``."""
    for h in range(w.shape[0]):
        for a in range(w.shape[1]):
            out[a, h] = w[h, a]
    return out


@fused
def chosen(q, act, out) -> None:
    """``out[t]`` := ``q[act[t], t]`` for ``q`` (A, N): a pass per action (a select the
    compiler vectorises, where a gather is not)."""
    out[:] = q[0]
    for a in range(1, q.shape[0]):
        row = q[a]
        for t in range(out.shape[0]):
            if act[t] == a:
                out[t] = row[t]


@fused
def best_legal(q, legal, valid, out) -> None:
    """``out[t]`` := max over legal (``legal`` (A, N)) and valid actions ``a`` of
    ``q[a, t]`` (-inf if none)."""
    out[:] = -np.inf
    for a in range(q.shape[0]):
        if valid[a]:
            row, allowed = q[a], legal[a]
            for t in range(out.shape[0]):
                if allowed[t] and row[t] > out[t]:
                    out[t] = row[t]


@fused
def online_choice_value(online, q, legal, valid, out) -> None:
    """Double Q: ``out[t]`` := ``q[a*, t]`` at the legal (``legal`` (A, N)) and valid
    action ``a*`` whose ``online[a, t]`` is largest, the first such on a tie (as
    ``argmax`` picks it); -inf if none is legal."""
    top = np.empty(out.shape[0], np.float32)
    top[:] = -np.inf
    out[:] = -np.inf
    for a in range(q.shape[0]):
        if valid[a]:
            row, value, allowed = online[a], q[a], legal[a]
            for t in range(out.shape[0]):
                if allowed[t] and row[t] > top[t]:
                    top[t] = row[t]
                    out[t] = value[t]


@fused
def independent_errors(c, best, reward, terminal, next_states, per_state, gamma, weight, grad_c):
    """Deep IQL's and hysteretic DQN's loss of one seed, each agent ``i`` its own TD target
    ``y_it = r_t + γ (1 - terminal_t) best_i(s'_t)`` (``best`` (n, N), or (n, S) at every
    state where ``per_state``): ``Σ_it w (c_it - y_it)² / (N n)``, ``w`` = ``weight``
    where ``c_it > y_it`` (a negative TD error), else 1; ``grad_c`` := its gradient
    ``2 w (c_it - y_it) / (N n)``. Returns the loss."""
    n, count = c.shape
    share = np.float32(count * n)
    loss = 0.0
    for i in range(n):
        for t in range(count):
            alive = np.float32(0.0) if terminal[t] else np.float32(1.0)
            after = best[i, next_states[t]] if per_state else best[i, t]
            error = c[i, t] - (reward[t] + gamma * alive * after)
            w = weight if error > 0.0 else np.float32(1.0)
            loss += w * error * error / share
            grad_c[i, t] = np.float32(2.0) * w * error / share
    return loss


@fused
def network_backward_features(w2, x, hidden, grad_q, grad_hidden, grads) -> None:
    """Gradients of one network on feature inputs ``x`` (F, N) from ``grad_q`` (A, N),
    the loss's gradient with respect to every output."""
    gw1, gb1, gw2, gb2 = grads
    dense_backward(hidden, grad_q, gw2, gb2)
    through_relu(w2, hidden, grad_q, grad_hidden)
    dense_backward(x, grad_hidden, gw1, gb1)


@fused
def agent_backward_features(net, grads, g, x, hidden, act, grad_c, grad_q, grad_hidden) -> None:
    """Gradients of group ``g``'s agent network on feature inputs
    (:func:`~cmarlcd.learners.deep.fused.networks.network_backward`), from ``grad_c``
    (N,), the loss's gradient with respect to the Q-value of each transition's action
    ``act`` (N,)."""
    for a in range(grad_q.shape[0]):
        row = grad_q[a]
        for t in range(act.shape[0]):
            row[t] = grad_c[t] if act[t] == a else np.float32(0.0)
    network_backward(net, grads, g, x, hidden, grad_q, grad_hidden)


@fused
def agent_backward_tables(w2t, hidden, states, act, grad_c, scratch, grads) -> None:
    """Gradients of one agent network on one-hot inputs: ``grad_q`` (S, A) gathers each
    state's ``∂L/∂Q`` of the transitions' actions."""
    grad_q, grad_hidden, grad_w2t = scratch
    grad_q[:] = 0.0
    for t in range(states.shape[0]):
        grad_q[states[t], act[t]] += grad_c[t]
    net_tables_backward(w2t, hidden, grad_q, grad_hidden, grad_w2t, grads)


# ------------------------------------------------------------------ the step


@fused
def agents_forward(
    agents, target_agents, b, inputs, c, best, hidden, kept, targets, double_q
) -> None:
    """Every agent of seed ``b``: ``c`` (n, N) the online Q of each transition's action
    (``hidden`` keeps what the backward pass reads), and where ``targets``, ``best`` the
    target networks' best legal Q (with ``double_q``, their Q at the online networks'
    best legal action): (n, N) at each transition's next state, or, for integer states
    whose masks are per state, (n, S) at every state. ``inputs``: see :func:`td_step`
    (a step without ``targets`` reads neither the next states nor the target networks,
    and may pass the online ones for them)."""
    w1, b1, w2, b2 = agents[:4]
    tw1, tb1, tw2, tb2 = target_agents[:4]
    index, x, nx, states, next_states, actions, legal_of, own_dim = inputs
    n, count = c.shape
    units, width = w2.shape[1], w2.shape[2]
    q = np.empty((width, count), np.float32)
    online = np.empty((width, count if double_q else 0), np.float32)
    legal = np.empty((width, count), np.bool_)
    act = np.empty(count, np.int64)
    rows = w1.shape[1] if index else 0
    table = np.empty((rows, width), np.float32)
    online_table = np.empty((rows if double_q else 0, width), np.float32)
    w2t = np.empty((width, units), np.float32)
    target_hidden = np.empty_like(hidden[0])
    for i in range(n):
        g = b * n + i
        act[:] = actions[:, i]
        if index:  # one hidden layer: state-major (S, H)
            net_tables(w1[g], b1[g], transposed(w2[g], w2t), b2[g], hidden[i, 0], table)
            for t in range(count):
                c[i, t] = table[states[t], act[t]]
            if not targets:
                continue
            if double_q:
                online_table[:] = table
            net_tables(tw1[g], tb1[g], transposed(tw2[g], w2t), tb2[g], target_hidden[0], table)
            if legal_of[0]:  # the batch's own masks: every transition's next Q-values
                for a in range(width):
                    for t in range(count):
                        q[a, t] = table[next_states[t], a]
                legal_of_agent(legal_of, b, i, next_states, legal)
                if double_q:
                    for a in range(width):
                        for t in range(count):
                            online[a, t] = online_table[next_states[t], a]
                    online_choice_value(online, q, legal, kept[i], best[i])
                else:
                    best_legal(q, legal, kept[i], best[i])
            else:  # masks per state: the best of each state
                chooser = online_table if double_q else table
                best_of_states(chooser, table, legal_of[2], b, i, kept[i], best[i])
        else:
            lo = 0 if own_dim == 0 else x.shape[0] - (n - i) * own_dim
            hi = x.shape[0] if own_dim == 0 else lo + own_dim
            network_forward(agents, g, x[lo:hi], hidden[i], q)
            chosen(q, act, c[i])
            if not targets:
                continue
            if double_q:  # the online networks at the next states (hidden units unkept)
                network_forward(agents, g, nx[lo:hi], target_hidden, online)
            network_forward(target_agents, g, nx[lo:hi], target_hidden, q)
            legal_of_agent(legal_of, b, i, next_states, legal)
            if double_q:
                online_choice_value(online, q, legal, kept[i], best[i])
            else:
                best_legal(q, legal, kept[i], best[i])


@fused
def best_of_states(chooser, table, state_legal, b, i, valid, out) -> None:
    """``out[s]`` := ``table[s, a*]`` at agent ``i``'s legal (``state_legal`` (B, S, n,
    A), or every action where it is empty) and valid action ``a*`` whose ``chooser[s,
    a]`` is largest, the first on a tie (-inf if none): the largest of ``table[s]`` where
    ``chooser`` is ``table``, double Q's value where it is the online networks' table."""
    masked = state_legal.shape[0] > 0
    for s in range(table.shape[0]):
        top, value = -np.inf, -np.inf
        for a in range(table.shape[1]):
            allowed = valid[a] and (not masked or state_legal[b, s, i, a])
            if allowed and chooser[s, a] > top:
                top = chooser[s, a]
                value = table[s, a]
        out[s] = value


@fused
def legal_of_agent(legal_of, b, i, next_states, out) -> None:
    """Agent ``i``'s legal actions at each next state, action-major (A, N): the batch's
    own masks, the per-state masks of integer states, or every action."""
    per_sample, next_legal, state_legal = legal_of
    if per_sample:
        for t in range(out.shape[1]):
            for a in range(out.shape[0]):
                out[a, t] = next_legal[b, t, i, a]
    elif state_legal.shape[0]:
        for t in range(out.shape[1]):
            for a in range(out.shape[0]):
                out[a, t] = state_legal[b, next_states[t], i, a]
    else:
        out[:] = True


@fused
def agents_backward(agents, grads, b, inputs, grad_c, hidden) -> None:
    """Every agent of seed ``b``: gradients from ``grad_c`` (n, N), ∂L/∂c."""
    w1, w2 = agents[0], agents[2]
    gw1, gb1, gw2, gb2 = grads[:4]
    index, x, states, actions, own_dim = inputs[0], inputs[1], inputs[3], inputs[5], inputs[7]
    n, count = grad_c.shape
    units, width = w2.shape[1], w2.shape[2]
    act = np.empty(count, np.int64)
    # two buffers (a layer's gradient is made from the next one's): (2, H, N), or (2, S, H)
    grad_hidden = np.empty((2, hidden.shape[2], hidden.shape[3]), np.float32)
    rows = w1.shape[1] if index else 0
    w2t = np.empty((width, units), np.float32)
    grad_w2t = np.empty((width, units), np.float32)
    tables = (np.empty((rows, width), np.float32), grad_hidden[0], grad_w2t)
    grad_q = np.empty((width, 0 if index else count), np.float32)
    for i in range(n):
        g = b * n + i
        act[:] = actions[:, i]
        if index:
            w2t = transposed(w2[g], w2t)
            parts = (gw1[g], gb1[g], gw2[g], gb2[g])
            agent_backward_tables(w2t, hidden[i, 0], states, act, grad_c[i], tables, parts)
        else:
            lo = 0 if own_dim == 0 else x.shape[0] - (n - i) * own_dim
            hi = x.shape[0] if own_dim == 0 else lo + own_dim
            agent_backward_features(
                agents, grads, g, x[lo:hi], hidden[i], act, grad_c[i], grad_q, grad_hidden
            )


@fused
def td_step(nets, grads, batch, legal_of, valid, shape, optimiser, cache, shared) -> float:
    """One step: the summed TD losses of every seed (paper Section V-A/B), their
    gradients left in ``grads``, and Adam's update of every parameter, seed by seed.

    ``nets``: (agents, target agents, mixer, target mixer), each a tuple of B-stacked
    arrays as the PyTorch modules hold them (agents seed-major, B*n groups; their layers
    as :mod:`~cmarlcd.learners.deep.fused.networks` lays them out, the middle layers
    stacked: integer states take one hidden layer only); ``grads``:
    (agents', mixer's). ``batch``: (state features (B, N, D) or integer states (B, N),
    their next states likewise, actions (B, N, n), reward, terminal (B, N)); ``legal_of``:
    (whether the batch has its own masks, them (B, N, n, A), per-state masks (B, S, n, A)
    or empty); ``valid`` (n, A): each agent's real actions. ``shape``: (qmix, index,
    discount, own_dim: features of each agent's own observation or 0, mixer_dim: the
    leading features the mixer reads, mixer hidden units, double Q, the norm each
    seed's gradient is clipped to (0 for none: :func:`clip_seed`), whether each agent
    learns from its own target (deep IQL, hysteretic DQN: :func:`independent_errors`) and
    the weight of its negative TD errors). ``optimiser``: the flat
    parameters, gradients (the same memory as ``grads``) and Adam's two moments, and
    Adam's settings (:func:`adam`). ``cache``: (refresh, table (B, S)): for integer
    states with masks per state, each seed's target ``Q_tot`` at every state, kept
    between steps (it changes only when the target networks or the masks do) and
    recomputed where ``refresh`` (at every step with double Q: the online networks
    choose the actions). ``shared``: (whether the agents share one network, its
    gradients): where they do, ``nets``' agents are its per-agent layers
    (:func:`spread_shared`), their gradients gathered into its own before the seed's
    update (:func:`gather_shared`), and ``optimiser`` holds its parameters.
    """
    agents, target_agents, mixer, target_mixer = nets
    refresh, target_table = cache
    agent_grads, mixer_grads = grads
    features, next_features, states, next_states, actions, reward, terminal = batch
    qmix, index, gamma, own_dim, mixer_dim, units, double_q, clip, independent, weight = shape
    seeds, count, n = actions.shape
    hidden_units, layers = agents[0].shape[2], agents[4].shape[0] + 1
    if index:  # state-major tables (S, H) of the one hidden layer
        hidden = np.empty((n, 1, agents[0].shape[1], hidden_units), np.float32)
        x = np.empty((0, count), np.float32)
        nx = np.empty((0, count), np.float32)
    else:
        hidden = np.empty((n, layers, hidden_units, count), np.float32)
        x = np.empty((features.shape[2], count), np.float32)
        nx = np.empty((features.shape[2], count), np.float32)
    # integer states with masks per state: the target's Q_tot is a function of the next
    # state alone, so it is mixed once per state (S) and read at each transition (N)
    per_state = index and not legal_of[0]
    n_states = agents[0].shape[1] if per_state else 0
    every_state = np.arange(n_states)
    c = np.empty((n, count), np.float32)
    best = np.empty((n, n_states if per_state else count), np.float32)
    grad_c = np.empty((n, count), np.float32)
    q_tot = np.empty(count, np.float32)
    next_tot = np.empty(count, np.float32)
    grad = np.empty(count, np.float32)
    columns = count if qmix and not index else 0  # the feature mixer's, (units, N)
    embed = mixer[10].shape[2]  # two-layer hypernetworks' hidden units (0: one layer)
    scratch = (
        np.empty((n * units, columns), np.float32),
        np.empty((units, columns), np.float32),
        np.empty((units, columns), np.float32),
        np.empty((units, columns), np.float32),
        np.empty((units, columns), np.float32),
        np.empty((embed, columns), np.float32),
        np.empty((embed, columns), np.float32),
        np.empty((embed, columns), np.float32),
    )
    tables = mixer[0].shape[1] if qmix and index else 0  # the integer-state mixer's
    work = state_scratch(tables, n, units, max(count, n_states) if tables else 0)
    loss = 0.0
    discount = np.float32(gamma)
    for b in range(seeds):
        if not index:
            transpose_into(features[b], x)
            transpose_into(next_features[b], nx)
        inputs = (index, x, nx, states[b], next_states[b], actions[b], legal_of, own_dim)
        targets = refresh or not per_state or double_q or independent
        agents_forward(agents, target_agents, b, inputs, c, best, hidden, valid, targets, double_q)
        if independent:  # each agent its own target: no mixer, no kept table
            loss += independent_errors(
                c, best, reward[b], terminal[b], next_states[b], per_state, discount,
                np.float32(weight), grad_c,
            )  # fmt: skip
            zero_seed(optimiser[1], b, seeds)
        else:
            mixed, next_mixed = x[:mixer_dim], nx[:mixer_dim]
            if targets:
                at = every_state if per_state else next_states[b]
                target_tot = target_table[b] if per_state else next_tot
                mix(qmix, target_mixer, b, best, next_mixed, at, index, scratch, work, target_tot)
            if per_state:
                for t in range(count):
                    next_tot[t] = target_table[b, next_states[b, t]]
            mix(qmix, mixer, b, c, mixed, states[b], index, scratch, work, q_tot)
            for t in range(count):
                alive = np.float32(0.0) if terminal[b, t] else np.float32(1.0)
                error = q_tot[t] - (reward[b, t] + discount * alive * next_tot[t])
                loss += error * error / count
                grad[t] = np.float32(2.0) * error / np.float32(count)
            zero_seed(optimiser[1], b, seeds)
            mix_backward(
                qmix, mixer, mixer_grads, b, c, mixed, states[b], index, scratch, work, grad, grad_c
            )
        agents_backward(agents, agent_grads, b, inputs, grad_c, hidden)
        if shared[0]:
            gather_shared(agent_grads, shared[1], b, n)
        if clip > 0.0:
            clip_seed(optimiser[1], b, seeds, clip)
        update_seed(optimiser, b, seeds)
    return loss
