"""The distributed sensor network (DSN) task of Section V-A, one module per job:
:mod:`~.layout` (the rules at any size), :mod:`~.kernels` (the paper's grid: the
compiled transition and :data:`SPEC`), :mod:`~.sized` (any size: :func:`make_spec`),
:mod:`~.env` (the PettingZoo ``ParallelEnv``) and :mod:`~.render` (a text picture)."""

from cmarlcd.games.sensor_network import kernels
from cmarlcd.games.sensor_network.env import SensorNetworkEnv
from cmarlcd.games.sensor_network.kernels import *  # noqa: F403  (the names in kernels.__all__)
from cmarlcd.games.sensor_network.render import render_text
from cmarlcd.games.sensor_network.sized import make_spec

__all__ = [*kernels.__all__, "SensorNetworkEnv", "make_spec", "render_text"]
