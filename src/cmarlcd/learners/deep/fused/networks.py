"""The agent networks of the fused CPU step (:mod:`cmarlcd.learners.deep.fused.kernels`) at
any depth, on feature inputs: forward and hand-derived backward through the first layer,
the middle layers and the output layer, and the spread and gather of a network the agents
share.

A network's layers, as the kernels take them: ``(w1, b1, w2, b2, wm, bm)``, the first and
output layers' weights (groups, I, H) and (groups, H, A) and biases, then the middle
layers stacked layer-major, ``wm`` (L - 1, groups, H, H) and ``bm`` (L - 1, groups, H),
empty (L - 1 = 0) for one hidden layer. For group ``g`` on inputs ``x`` (F, N), kept
feature-major as every array of the fused step:

* ``h_0 = ReLU(W1ᵀx + b1)``, ``h_l = ReLU(Wm_lᵀ h_{l-1} + bm_l)`` for ``l = 1 .. L-1``,
  ``Q = W2ᵀ h_{L-1} + b2`` (``cmarlcd.learners.deep.agent_networks``' ``through``);
* backward from ``∂L/∂Q``: ``∂L/∂W2 = h_{L-1} (∂L/∂Q)ᵀ``, then each layer's gradient with
  respect to its ReLU's input, ``δ_l = [h_l > 0] · W_{l+1} δ_{l+1}``, its weights'
  ``h_{l-1} δ_lᵀ`` (``x`` for the first), its bias the rows' sums.

With one hidden layer the operations are those of the one-layer kernels in the same
order, so the fused step's numbers at one layer are unchanged by the middle layers'
support (bit for bit: tests and ``benchmarks/compare_stores.py``).
"""

from __future__ import annotations

import numpy as np

from cmarlcd.learners.deep.fused.layers import dense_backward, dense_forward, fused, relu_inplace


def own_starts(n_features: int, n: int, own_dim: int) -> np.ndarray:
    """The first feature each of ``n`` agents' networks reads: its own observation's,
    the last ``n * own_dim`` features in agent order (the layout ``[s, o_1, ..., o_n]`` of
    ``cmarlcd.learners.deep.agent_networks``), or 0 (all of them)."""
    if not own_dim:
        return np.zeros(n, np.int64)
    return np.array([n_features - (n - i) * own_dim for i in range(n)], np.int64)


@fused
def network_forward(net, g: int, x, hidden, q) -> None:
    """Group ``g``'s network ``net`` on ``x`` (F, N): ``hidden`` (L, H, N) := every hidden
    layer's ReLU (the backward pass reads them), ``q`` (A, N) := its outputs."""
    w1, b1, w2, b2, wm, bm = net
    dense_forward(w1[g], b1[g], x, hidden[0])
    relu_inplace(hidden[0])
    for layer in range(wm.shape[0]):
        dense_forward(wm[layer, g], bm[layer, g], hidden[layer], hidden[layer + 1])
        relu_inplace(hidden[layer + 1])
    dense_forward(w2[g], b2[g], hidden[wm.shape[0]], q)


@fused
def through_relu(w, hidden, grad_out, grad_hidden) -> None:
    """``grad_hidden`` (H, M) := ``w grad_out`` (``w`` (H, O), ``grad_out`` (O, M)) where
    ``hidden`` (H, M), a ReLU's output, is positive, else 0: the gradient with respect to
    the ReLU's input."""
    for h in range(hidden.shape[0]):
        row, out = hidden[h], grad_hidden[h]
        out[:] = 0.0
        for a in range(grad_out.shape[0]):
            weight, d = w[h, a], grad_out[a]
            for m in range(row.shape[0]):
                out[m] += weight * d[m]
        for m in range(row.shape[0]):
            if not row[m] > 0.0:
                out[m] = 0.0


@fused
def network_backward(net, grads, g: int, x, hidden, grad_q, grad_hidden) -> None:
    """Group ``g``'s gradients (``grads``, laid out as ``net``) += those of
    :func:`network_forward` on ``x`` from ``grad_q`` (A, N), the loss's gradient with
    respect to every output; ``grad_hidden`` (2, H, N) is scratch."""
    w2, wm = net[2], net[4]
    gw1, gb1, gw2, gb2, gwm, gbm = grads
    last = wm.shape[0]
    dense_backward(hidden[last], grad_q, gw2[g], gb2[g])
    through_relu(w2[g], hidden[last], grad_q, grad_hidden[0])
    here = 0
    for layer in range(last - 1, -1, -1):  # middle layer l maps h_l to h_{l+1}
        dense_backward(hidden[layer], grad_hidden[here], gwm[layer, g], gbm[layer, g])
        through_relu(wm[layer, g], hidden[layer], grad_hidden[here], grad_hidden[1 - here])
        here = 1 - here
    dense_backward(x, grad_hidden[here], gw1[g], gb1[g])


@fused
def spread_shared(shared, agents, n: int) -> None:
    """Each agent's layers (``agents``: B*n groups, seed-major) from one network shared by
    the agents (``shared``: B groups, the agent's one-hot index the first layer's last
    ``n`` inputs): agent ``i``'s index row folded into its first bias, the other layers
    copied."""
    w1, b1, w2, b2, wm, bm = shared
    aw1, ab1, aw2, ab2, awm, abm = agents
    inputs = aw1.shape[1]
    for b in range(w1.shape[0]):
        for i in range(n):
            g = b * n + i
            aw1[g] = w1[b, :inputs]
            ab1[g] = b1[b] + w1[b, inputs + i]
            aw2[g] = w2[b]
            ab2[g] = b2[b]
            for layer in range(wm.shape[0]):
                awm[layer, g] = wm[layer, b]
                abm[layer, g] = bm[layer, b]


@fused
def gather_shared(agent_grads, shared_grads, b: int, n: int) -> None:
    """Seed ``b``'s shared gradients += its agents' (the chain rule through
    :func:`spread_shared`), the agents' then zeroed for the next step."""
    gw1, gb1, gw2, gb2, gwm, gbm = shared_grads
    aw1, ab1, aw2, ab2, awm, abm = agent_grads
    inputs = aw1.shape[1]
    for i in range(n):
        g = b * n + i
        gw1[b, :inputs] += aw1[g]
        gw1[b, inputs + i] += ab1[g]
        gb1[b] += ab1[g]
        gw2[b] += aw2[g]
        gb2[b] += ab2[g]
        aw1[g], ab1[g], aw2[g], ab2[g] = 0.0, 0.0, 0.0, 0.0
        for layer in range(gwm.shape[0]):
            gwm[layer, b] += awm[layer, g]
            gbm[layer, b] += abm[layer, g]
            awm[layer, g], abm[layer, g] = 0.0, 0.0


def stacked(layers: list[np.ndarray], out: np.ndarray) -> np.ndarray:
    """``out`` (L - 1, ...) := the middle layers' arrays, one per layer (the model's own
    parameters, which Adam updates in place); returns ``out``."""
    for layer, array in enumerate(layers):
        out[layer] = array
    return out
