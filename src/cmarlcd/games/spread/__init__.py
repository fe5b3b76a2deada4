"""MPE's simple_spread (``mpe2`` 1.1.1, discrete actions), one module per job:
:mod:`~.kernels` (the compiled physics), :mod:`~.rules` (a task and its spec) and
:mod:`~.env` (the PettingZoo ``ParallelEnv``)."""

from cmarlcd.games.spread.env import SimpleSpreadEnv
from cmarlcd.games.spread.rules import SimpleSpread

__all__ = ["SimpleSpread", "SimpleSpreadEnv"]
