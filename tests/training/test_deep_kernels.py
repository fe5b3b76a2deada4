"""The compiled forward pass of a deep side's agent networks: the very numbers of the
layers' definition in the networks' float types, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from cmarlcd.training import deep_kernels
from cmarlcd.training.deep_kernels import Weights

FEATURES, HIDDEN, WIDTH, AGENTS = 12, 49, 6, 3


def random_weights(rng: np.random.Generator) -> Weights:
    shapes = ((AGENTS, FEATURES, HIDDEN), (AGENTS, HIDDEN), (AGENTS, HIDDEN, WIDTH))
    return Weights(
        *(rng.standard_normal(shape).astype(np.float32) for shape in shapes),
        rng.standard_normal((AGENTS, WIDTH)).astype(np.float32),
        np.zeros((AGENTS, 0, HIDDEN, HIDDEN), np.float32),  # one hidden layer
        np.zeros((AGENTS, 0, HIDDEN), np.float32),
    )


def reference_hidden(weights: Weights, agent: int, x: np.ndarray) -> np.ndarray:
    """ReLU(x W1 + b1), one unit at a time, each sum over the features in order, every
    operation rounded to float32 (NumPy's float32 scalars)."""
    out = np.zeros(HIDDEN, np.float32)
    for h in range(HIDDEN):
        z = weights.b1[agent, h]
        for f in range(FEATURES):
            z = np.float32(z + np.float32(x[f] * weights.w1[agent, f, h]))
        out[h] = z if z > 0 else np.float32(0.0)
    return out


def reference_output(weights: Weights, agent: int, hidden: np.ndarray, a: int) -> float:
    """b2[a] + sum_h hidden[h] W2[h, a], summed in float64 (Python floats) in order."""
    q = float(weights.b2[agent, a])
    for h in range(HIDDEN):
        q += float(hidden[h]) * float(weights.w2[agent, h, a])
    return q


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_forward_pass_is_the_layers_definition_bit_for_bit(seed) -> None:
    rng = np.random.default_rng(seed)
    weights = random_weights(rng)
    hidden = np.zeros(HIDDEN, np.float32)
    for _ in range(20):
        x = rng.random(FEATURES).astype(np.float32)
        x[rng.random(FEATURES) < 0.4] = 0.0  # units destroyed: features of value 0
        for agent in range(AGENTS):
            expected = reference_hidden(weights, agent, x)
            deep_kernels.hidden_layer(weights, agent, x, hidden)
            assert np.array_equal(hidden, expected)
            assert (hidden == 0).any() and (hidden > 0).any()  # both sides of the ReLU
            outputs = [reference_output(weights, agent, expected, a) for a in range(WIDTH)]
            for a in range(WIDTH):
                assert deep_kernels.output_unit(weights, agent, hidden, a) == outputs[a]
            legal = rng.random(WIDTH) < 0.7
            legal[rng.integers(WIDTH)] = True
            best = max((q, -a) for a, q in enumerate(outputs) if legal[a])
            greedy = deep_kernels.greedy_agent(weights, agent, x, legal, WIDTH, hidden)
            assert greedy == -best[1]
