"""The mixers of the fused CPU step (:mod:`cmarlcd.learners.deep.fused.kernels`): QMIX's
monotonic mixing network, forward and hand-derived backward, and VDN's sum.

QMIX (paper Section V-B) for seed ``b``, agents' values ``c_i`` at state ``s``:
``Q_tot = Σ_k ELU(Σ_i c_i |W1(s)|_ik + B1(s)_k) |W2(s)|_k + V(s)``, with hypernetworks
``W1, B1, W2`` (one linear layer each; or, for ``W1`` and ``W2``, two: ``Linear → ReLU →
Linear``, EPyMARL's ``hypernet_layers: 2``) and ``V(s) = v2ᵀ ReLU(V1(s)) + v2_b``. Through
``|·|`` the gradient is multiplied by ``sign`` (0 at 0), through ReLU by ``[out > 0]``,
through ELU by ``exp(p) = ELU(p) + 1`` for ``p <= 0``, as PyTorch's backward functions do.

Two layouts, one per kind of state:

* **features** (``x`` (F, N)): the hypernetworks are dense layers over the batch, kept
  feature-major (``(units, N)``), every inner loop over the N transitions;
* **integer states** (one-hot inputs): a hypernetwork's output at state ``s`` is its
  weights' row ``s`` plus its bias, so the mixer's weights are tables over the S states,
  made once per seed; each transition reads its state's rows and every inner loop runs
  over the K mixing units; the gradients gather per state and go through ``|·|`` once
  (one-layer hypernetworks only).

The mixer's parameters, as the kernels take them: ``(hw1, hw1_b, hb1, hb1_b, hw2, hw2_b,
v1, v1_b, v2, v2_b, e1, e1_b, e2, e2_b)``, each B-stacked: the weights' hypernetworks'
(last) layers, B1's, V's two layers, then the first layers of two-layer ``W1`` and ``W2``
hypernetworks (``e1`` (B, F, E)), empty (F = E = 0) for one-layer ones.
"""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.deep.fused.layers import (
    dense_backward,
    dense_forward,
    fused,
    inlined,
    relu_inplace,
)
from cmarlcd.learners.deep.fused.networks import through_relu


@inlined
def sign(w) -> float:
    return np.float32(1.0) if w > 0.0 else (np.float32(-1.0) if w < 0.0 else np.float32(0.0))


@inlined
def elu(p) -> float:
    return p if p > 0.0 else expm1_negative(p)


@fused
def elu_of(values):
    """ELU of every value of a float32 array (the kernels' own, for tests)."""
    out = np.empty_like(values)
    for j in range(values.shape[0]):
        out[j] = elu(values[j])
    return out


@inlined
def expm1_negative(p) -> float:
    """``exp(p) - 1`` of a float32 ``p <= 0``, correctly rounded to float32 (within half
    an ulp, checked in the tests), in arithmetic the compiler vectorises: numba's
    ``np.expm1`` is a scalar library call, 8x slower, and was most of QMIX's mixing.

    In float64: ``p = k ln 2 + r`` with ``|r| <= ln 2 / 2``, ``expm1(r)`` by its Taylor
    series to ``r⁹/9!`` (error below 10⁻¹¹), ``2^k`` as a product of the powers of two
    of ``-k``'s bits, and ``expm1(p) = 2^k expm1(r) + (2^k - 1)``; below -87 it is -1."""
    x = max(np.float64(p), -87.0)
    k = np.floor(x * 1.4426950408889634 + 0.5)
    r = x - k * 0.6931471805599453
    # written out: a loop over a tuple here is not unrolled, and the call not vectorised
    series = 1.0 / 40320 + r * (1.0 / 362880)
    series = 1.0 / 5040 + r * series
    series = 1.0 / 720 + r * series
    series = 1.0 / 120 + r * series
    series = 1.0 / 24 + r * series
    series = 1.0 / 6 + r * series
    series = 0.5 + r * series
    series = 1.0 + r * series
    bits = np.int64(-k)
    scale = 0.5 if bits & 1 else 1.0
    scale *= 0.25 if bits & 2 else 1.0
    scale *= 2.0**-4 if bits & 4 else 1.0
    scale *= 2.0**-8 if bits & 8 else 1.0
    scale *= 2.0**-16 if bits & 16 else 1.0
    scale *= 2.0**-32 if bits & 32 else 1.0
    scale *= 2.0**-64 if bits & 64 else 1.0
    return np.float32(scale * (r * series) + (scale - 1.0))


# ------------------------------------------------------------------ feature states


@fused
def qmix_forward(mixer, b: int, c, x, scratch, q_tot) -> None:
    """QMIX's ``Q_tot`` (N,) of seed ``b`` for the agents' values ``c`` (n, N) at state
    features ``x`` (F, N). ``scratch`` keeps, for the backward pass: W1(s) (n*K, N),
    B1(s)+Σ (pre-activation) and ELU (K, N) each, W2(s), ReLU(V1(s)) (K, N), and the
    two-layer hypernetworks' hidden layers (E, N) (then a scratch of their gradient)."""
    hw1, hw1_b, hb1, hb1_b, hw2, hw2_b, v1, v1_b, v2, v2_b, e1, e1_b, e2, e2_b = mixer
    w1s, pre, hid, w2s, val, embed1, embed2 = scratch[:7]
    n, count = c.shape
    k_units = pre.shape[0]
    hyper_forward(e1, e1_b, hw1, hw1_b, b, x, embed1, w1s)
    dense_forward(hb1[b], hb1_b[b], x, pre)
    hyper_forward(e2, e2_b, hw2, hw2_b, b, x, embed2, w2s)
    dense_forward(v1[b], v1_b[b], x, val)
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
            e[t] = elu(p[t])
            q_tot[t] += e[t] * abs(w[t]) + v[t] * weight


@fused
def qmix_backward(mixer, grads, b: int, c, x, scratch, grad, grad_c) -> None:
    """Gradients of :func:`qmix_forward` for ``grad`` = ∂L/∂Q_tot (N,): into the mixer's
    ``grads`` (seed ``b``'s rows) and ``grad_c`` (n, N), ∂L/∂c. Overwrites ``scratch``."""
    v2 = mixer[8]
    g_hw1, g_hw1_b, g_hb1, g_hb1_b, g_hw2, g_hw2_b, g_v1, g_v1_b, g_v2, g_v2_b = grads[:10]
    w1s, pre, hid, w2s, val, embed1, embed2, grad_embed = scratch
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
            w[t] = grad[t] * e[t] * sign(w[t])  # through |·|
            p[t] = d_hid if p[t] > 0.0 else d_hid * (e[t] + np.float32(1.0))  # ELU
            v[t] = v_out
        g_v2[b, k, 0] += total
        for i in range(n):  # ∂L/∂c_i and ∂L/∂W1(s)_ik, through |·|
            wi, ci, gi = w1s[i * k_units + k], c[i], grad_c[i]
            for t in range(count):
                gi[t] += p[t] * abs(wi[t])
                wi[t] = p[t] * ci[t] * sign(wi[t])
    hyper_backward(mixer[10], mixer[0], grads[10:12], (g_hw1, g_hw1_b), b, x, embed1, w1s,
                   grad_embed)  # fmt: skip
    dense_backward(x, pre, g_hb1[b], g_hb1_b[b])
    hyper_backward(mixer[12], mixer[4], grads[12:14], (g_hw2, g_hw2_b), b, x, embed2, w2s,
                   grad_embed)  # fmt: skip
    dense_backward(x, val, g_v1[b], g_v1_b[b])


@fused
def hyper_forward(first, first_b, last, last_b, b: int, x, embed, out) -> None:
    """A mixing weights' hypernetwork of seed ``b`` on ``x`` (F, N) into ``out``: its one
    layer (``last``), or, where ``first`` has inputs, ``embed`` (E, N) := ReLU of its
    first layer, then its last layer on that."""
    if first.shape[1] == 0:
        dense_forward(last[b], last_b[b], x, out)
    else:
        dense_forward(first[b], first_b[b], x, embed)
        relu_inplace(embed)
        dense_forward(last[b], last_b[b], embed, out)


@fused
def hyper_backward(first, last, first_grads, last_grads, b: int, x, embed, grad_out, grad_embed):
    """Seed ``b``'s gradients of :func:`hyper_forward` from ``grad_out``, ∂L/∂out:
    ``last_grads``, and through the ReLU of ``embed`` (``grad_embed`` (E, N) scratch)
    ``first_grads``, where it has two layers."""
    if first.shape[1] == 0:
        dense_backward(x, grad_out, last_grads[0][b], last_grads[1][b])
    else:
        dense_backward(embed, grad_out, last_grads[0][b], last_grads[1][b])
        through_relu(last[b], embed, grad_out, grad_embed)
        dense_backward(x, grad_embed, first_grads[0][b], first_grads[1][b])


# ------------------------------------------------------------------ integer states


@fused
def state_scratch(states: int, agents: int, units: int, count: int) -> tuple:
    """The integer-state mixer's work arrays: its tables over the states (|W1| (S, n*K),
    B1, |W2|, ReLU(V1) (S, K), V (S, 1)), each transition's pre-activations and ELUs
    (N, K), the tables' gradients (the first four's shapes) and a row of K."""
    return (
        np.empty((states, agents * units), np.float32),
        np.empty((states, units), np.float32),
        np.empty((states, units), np.float32),
        np.empty((states, units), np.float32),
        np.empty((states, 1), np.float32),
        np.empty((count, units), np.float32),
        np.empty((count, units), np.float32),
        np.empty((states, agents * units), np.float32),
        np.empty((states, units), np.float32),
        np.empty((states, units), np.float32),
        np.empty((states, 1), np.float32),
        np.empty((1, units), np.float32),
    )


@fused
def state_tables(mixer, b: int, work) -> None:
    """The mixer's weights of seed ``b`` at every state: each hypernetwork's row plus its
    bias (|W1(s)|, B1(s), |W2(s)|), ReLU(V1(s)) and V(s)."""
    hw1, hw1_b, hb1, hb1_b, hw2, hw2_b, v1, v1_b, v2, v2_b = mixer[:10]
    w1s, b1s, w2s, v1s, value = work[0], work[1], work[2], work[3], work[4]
    units = b1s.shape[1]
    for s in range(w1s.shape[0]):
        for j in range(w1s.shape[1]):
            w1s[s, j] = abs(hw1[b, s, j] + hw1_b[b, j])
        total = v2_b[b, 0]
        for k in range(units):
            b1s[s, k] = hb1[b, s, k] + hb1_b[b, k]
            w2s[s, k] = abs(hw2[b, s, k] + hw2_b[b, k])
            v = v1[b, s, k] + v1_b[b, k]
            v1s[s, k] = v if v > 0.0 else np.float32(0.0)
            total += v1s[s, k] * v2[b, k, 0]
        value[s, 0] = total


@fused
def qmix_forward_states(mixer, b: int, c, states, work, q_tot) -> None:
    """QMIX's ``Q_tot`` (N,) of seed ``b`` for the agents' values ``c`` (n, N) at integer
    ``states`` (N,); ``work`` (:func:`state_scratch`) keeps what the backward pass reads.
    Four agents a pass over a state's row of K units (the rows are short: fewer passes)."""
    state_tables(mixer, b, work)
    w1s, b1s, w2s, value, pre, out = work[0], work[1], work[2], work[4], work[5], work[6]
    acc = work[11][0]
    n, count = c.shape
    units = b1s.shape[1]
    for t in range(count):
        s = states[t]
        for k in range(units):
            acc[k] = b1s[s, k]
        i = 0
        while i + 4 <= n:
            c0, c1, c2, c3 = c[i, t], c[i + 1, t], c[i + 2, t], c[i + 3, t]
            o0, o1, o2, o3 = i * units, (i + 1) * units, (i + 2) * units, (i + 3) * units
            for k in range(units):
                acc[k] += (
                    c0 * w1s[s, o0 + k]
                    + c1 * w1s[s, o1 + k]
                    + c2 * w1s[s, o2 + k]
                    + c3 * w1s[s, o3 + k]
                )
            i += 4
        while i < n:
            ci, o0 = c[i, t], i * units
            for k in range(units):
                acc[k] += ci * w1s[s, o0 + k]
            i += 1
        total = value[s, 0]
        for k in range(units):
            pre[t, k] = acc[k]
            out[t, k] = elu(acc[k])
            total += out[t, k] * w2s[s, k]
        q_tot[t] = total


@fused
def qmix_backward_states(mixer, grads, b: int, c, states, work, grad, grad_c) -> None:
    """Gradients of :func:`qmix_forward_states` for ``grad`` = ∂L/∂Q_tot (N,): into the
    mixer's ``grads`` (seed ``b``'s rows) and ``grad_c`` (n, N), ∂L/∂c."""
    w1s, b1s, w2s, pre, out = work[0], work[1], work[2], work[5], work[6]
    g1, gb1, g2, gv, d = work[7], work[8], work[9], work[10], work[11][0]
    n, count = c.shape
    units = b1s.shape[1]
    for table in (g1, gb1, g2, gv):
        table[:] = 0.0
    for t in range(count):
        s, g = states[t], grad[t]
        gv[s, 0] += g
        for k in range(units):  # ∂L/∂|W2(s)|, then ∂L/∂pre through ELU
            g2[s, k] += g * out[t, k]
            slope = np.float32(1.0) if pre[t, k] > 0.0 else out[t, k] + np.float32(1.0)
            d[k] = g * w2s[s, k] * slope
            gb1[s, k] += d[k]
        i = 0
        while i + 4 <= n:  # ∂L/∂c_i and ∂L/∂|W1(s)|_ik, four agents a pass
            c0, c1, c2, c3 = c[i, t], c[i + 1, t], c[i + 2, t], c[i + 3, t]
            o0, o1, o2, o3 = i * units, (i + 1) * units, (i + 2) * units, (i + 3) * units
            t0 = t1 = t2 = t3 = np.float32(0.0)
            for k in range(units):
                t0 += d[k] * w1s[s, o0 + k]
                t1 += d[k] * w1s[s, o1 + k]
                t2 += d[k] * w1s[s, o2 + k]
                t3 += d[k] * w1s[s, o3 + k]
                g1[s, o0 + k] += d[k] * c0
                g1[s, o1 + k] += d[k] * c1
                g1[s, o2 + k] += d[k] * c2
                g1[s, o3 + k] += d[k] * c3
            grad_c[i, t], grad_c[i + 1, t], grad_c[i + 2, t], grad_c[i + 3, t] = t0, t1, t2, t3
            i += 4
        while i < n:
            ci, o0, t0 = c[i, t], i * units, np.float32(0.0)
            for k in range(units):
                t0 += d[k] * w1s[s, o0 + k]
                g1[s, o0 + k] += d[k] * ci
            grad_c[i, t] = t0
            i += 1
    state_gradients(mixer, grads, b, work)


@fused
def state_gradients(mixer, grads, b: int, work) -> None:
    """The per-state gradients of :func:`qmix_backward_states` through ``|·|`` (the sign
    of each hypernetwork's output, recomputed) and ReLU into the hypernetworks' rows and
    biases of seed ``b``."""
    hw1, hw1_b, hw2, hw2_b, v2 = mixer[0], mixer[1], mixer[4], mixer[5], mixer[8]
    g_hw1, g_hw1_b, g_hb1, g_hb1_b, g_hw2, g_hw2_b, g_v1, g_v1_b, g_v2, g_v2_b = grads[:10]
    v1s, g1, gb1, g2, gv = work[3], work[7], work[8], work[9], work[10]
    for s in range(g1.shape[0]):
        total = gv[s, 0]
        g_v2_b[b, 0] += total
        for k in range(g2.shape[1]):
            g_v2[b, k, 0] += total * v1s[s, k]
            d = total * v2[b, k, 0] if v1s[s, k] > 0.0 else np.float32(0.0)
            g_v1[b, s, k] += d
            g_v1_b[b, k] += d
            g_hb1[b, s, k] += gb1[s, k]
            g_hb1_b[b, k] += gb1[s, k]
            d = g2[s, k] * sign(hw2[b, s, k] + hw2_b[b, k])
            g_hw2[b, s, k] += d
            g_hw2_b[b, k] += d
        for j in range(g1.shape[1]):
            d = g1[s, j] * sign(hw1[b, s, j] + hw1_b[b, j])
            g_hw1[b, s, j] += d
            g_hw1_b[b, j] += d


# ------------------------------------------------------------------ either mixer


@fused
def mix(qmix: bool, mixer, b, c, x, states, index, scratch, work, q_tot) -> None:
    """``Q_tot`` of seed ``b``: QMIX's mixer on features or integer states, or VDN's sum."""
    if qmix and index:
        qmix_forward_states(mixer, b, c, states, work, q_tot)
    elif qmix:
        qmix_forward(mixer, b, c, x, scratch, q_tot)
    else:
        q_tot[:] = 0.0
        for i in range(c.shape[0]):
            for t in range(c.shape[1]):
                q_tot[t] += c[i, t]


@fused
def mix_backward(qmix: bool, mixer, grads, b, c, x, states, index, scratch, work, grad, grad_c):
    """∂L/∂c (``grad_c`` (n, N)) from ∂L/∂Q_tot (``grad``), and QMIX's gradients."""
    if qmix and index:
        qmix_backward_states(mixer, grads, b, c, states, work, grad, grad_c)
    elif qmix:
        qmix_backward(mixer, grads, b, c, x, scratch, grad, grad_c)
    else:
        for i in range(c.shape[0]):
            grad_c[i] = grad
