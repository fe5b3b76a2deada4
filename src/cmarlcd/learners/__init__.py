"""Learners: CMARL-CD (coordination degree) and the paper's baselines, one file each.

* :mod:`~.coordination` -- CMARL-CD, Algorithms 1 and 2;
* :mod:`~.automata` -- the LA-OCA stand-in;
* :mod:`~.deep_config`, :mod:`~.value_decomposition`, :mod:`~.deep_agent` -- VDN and QMIX
  (the networks and the agent need the ``[deep]`` extra);
* :mod:`~.deep_coordination`, :mod:`~.degree_model` -- deep CMARL-CD, Algorithm 2 with
  networks (beyond the paper; the model needs the ``[deep]`` extra);

and what they share: the tabular protocol and object API (:mod:`~.tabular`), the
max-return indicator (:mod:`~.max_return`) and acting from tables (:mod:`~.policy`).
"""

from cmarlcd.learners.automata import LAOCA, AutomatonConfig
from cmarlcd.learners.coordination import (
    CMARLCD,
    CMARLCDStochastic,
    RepeatedConfig,
    StochasticConfig,
)
from cmarlcd.learners.deep_config import DeepConfig
from cmarlcd.learners.deep_coordination import DeepCMARLCDConfig

__all__ = [
    "CMARLCD",
    "LAOCA",
    "AutomatonConfig",
    "CMARLCDStochastic",
    "DeepCMARLCDConfig",
    "DeepConfig",
    "RepeatedConfig",
    "StochasticConfig",
]
