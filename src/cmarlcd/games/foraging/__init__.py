"""Level-Based Foraging (the ``lbforaging`` package's rules, 2.0.0), one module per job:
:mod:`~.kernels` (the compiled transition), :mod:`~.rules` (a task by name or number, and
its spec), :mod:`~.env` (the PettingZoo ``ParallelEnv``) and :mod:`~.render` (a text
picture)."""

from cmarlcd.games.foraging.env import ForagingEnv
from cmarlcd.games.foraging.render import render_text
from cmarlcd.games.foraging.rules import Foraging

__all__ = ["Foraging", "ForagingEnv", "render_text"]
