"""Learners: CMARL-CD (coordination degree), the paper's baselines and the classic
coordination learners, grouped by kind.

* :mod:`~.tabular` -- the tabular learners, one readable file each: CMARL-CD
  (Algorithms 1 and 2), the LA-OCA stand-in, the classic coordination learners, and the
  protocol they share;
* :mod:`~.deep` -- VDN, QMIX and deep CMARL-CD, B seeds in one model (the networks need
  the ``[deep]`` extra), with the fused CPU step in :mod:`~.deep.fused`;

and the rules both kinds share, free of either: the coordination-degree rules
(:mod:`~.degree_rules`, eqs. 2-3 and 14-15), the max-return indicator
(:mod:`~.max_return`, eqs. 1 and 16) and acting from per-agent values with the ε
schedule of eq. (18) (:mod:`~.policy`).

The names below are the learners' configs and classes; the 0.6 module paths
(``cmarlcd.learners.coordination``, ``cmarlcd.learners.fused_step``, ...) still import
for one release, with a :class:`DeprecationWarning` naming the new place.
"""

from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.tabular.automata import LAOCA, AutomatonConfig
from cmarlcd.learners.tabular.coordination import (
    CMARLCD,
    CMARLCDStochastic,
    RepeatedConfig,
    StochasticConfig,
)

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
