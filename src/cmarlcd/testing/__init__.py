"""Conformance checks a plug-in author runs on a new game or learner, as the project's
own tests run them on every registered one (PettingZoo ships its tests the same way).

>>> from cmarlcd.testing import check_game, check_learner
>>> check_game(my_spec)                 # or check_game(MyParallelEnv): every PettingZoo test
>>> check_learner(MyConfig())           # the loops' contract, on the tiny games below

* :func:`check_game` (:mod:`~.envs`): every PettingZoo conformance test that applies,
  through every standard conversion, observations of their spaces' dtype, and the
  ``ParallelEnv`` stepping exactly as the compiled kernels do;
* :func:`check_learner` (:mod:`~.learners`): the compiled loops against the object API,
  determinism by seed, legal greedy actions, both sides of a two-team game;
* :data:`CHAIN` and :data:`DUEL` (:mod:`~.games`): one-team and two-team games small
  enough to learn in a second;
* :func:`~.streams.stream_equivalence` (:mod:`~.streams`): whether a learner fed another's
  stream of visits learns what that one learns (deep CMARL-CD against the table).
"""

from cmarlcd.testing.envs import CHECKS, check_game
from cmarlcd.testing.games import CHAIN, DUEL
from cmarlcd.testing.learners import check_learner

__all__ = ["CHAIN", "CHECKS", "DUEL", "check_game", "check_learner"]
