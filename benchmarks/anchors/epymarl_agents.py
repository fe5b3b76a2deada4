"""EPyMARL with one more agent network: cmarl-cd's model class, one hidden layer.

EPyMARL's feed-forward agent (``use_rnn=False``) has two hidden layers (``fc1``, ReLU,
``rnn`` as a ``Linear``, ReLU, ``fc2``); cmarl-cd's agents have one (``W1``, ReLU,
``W2``). To tell whether that layer is what separates the two sides, the anchor runs
EPyMARL with :class:`OneHiddenLayerAgent` (``--agent one-layer``), everything else
EPyMARL's own.

EPyMARL has no hook for an agent from outside its tree, so this file is a launcher: run
from an EPyMARL checkout as ``python epymarl_agents.py src/main.py ARGS...``, it puts
``src`` on the path, adds the agent to EPyMARL's registry under :data:`NAME` and runs
``src/main.py`` as EPyMARL's own command would, with ``ARGS`` (``agent=one_layer`` among
them). Nothing in the checkout is changed.
"""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import torch
from torch import nn
from torch.nn import functional

#: The name EPyMARL's ``agent`` setting takes for :class:`OneHiddenLayerAgent`.
NAME = "one_layer"


class OneHiddenLayerAgent(nn.Module):
    """Q = W2 ReLU(W1 x + b1) + b2, with ``hidden_dim`` units (``torch.nn.Linear``'s
    initialisation, as EPyMARL's layers and cmarl-cd's). EPyMARL's controller hands every
    agent a hidden state and keeps what it returns: this network has none to carry, so it
    returns the one it was given."""

    def __init__(self, input_shape: int, args) -> None:
        super().__init__()
        self.hidden_dim = args.hidden_dim
        self.fc1 = nn.Linear(input_shape, args.hidden_dim)
        self.fc2 = nn.Linear(args.hidden_dim, args.n_actions)

    def init_hidden(self) -> torch.Tensor:
        return self.fc1.weight.new_zeros(1, self.hidden_dim)

    def forward(self, inputs: torch.Tensor, hidden_state: torch.Tensor):
        q = self.fc2(functional.relu(self.fc1(inputs)))
        return q, hidden_state.reshape(-1, self.hidden_dim)


def main(argv: list[str]) -> None:
    """Register the agent in the EPyMARL checkout at the working directory, then run
    ``argv[0]`` (its ``src/main.py``) with ``argv`` as its command line."""
    if not argv or not Path(argv[0]).is_file():
        raise SystemExit("usage: python epymarl_agents.py src/main.py ARGS... (in a checkout)")
    sys.path.insert(0, str(Path(argv[0]).resolve().parent))
    from modules.agents import REGISTRY  # EPyMARL's agent registry

    REGISTRY[NAME] = OneHiddenLayerAgent
    sys.argv = list(argv)
    runpy.run_path(argv[0], run_name="__main__")


if __name__ == "__main__":
    main(sys.argv[1:])
