"""How learners meet games: one loop, played through sides, for every game.

* :mod:`~.protocol` -- what the loop asks of a side (a leaf module);
* :mod:`~.loop` -- the one compiled loop (learning, greedy evaluation) for games of one
  or two teams, and plays that learn together;
* :mod:`~.tabular_side`, :mod:`~.deep_side`, :mod:`~.policy_side` -- the sides: a
  tabular learner, VDN / QMIX (``[deep]`` extra), a fixed joint policy;
* :mod:`~.tabular`, :mod:`~.deep`, :mod:`~.match` -- one-team runs of a tabular learner,
  seed-batched VDN / QMIX runs, two-team matches;
* :mod:`~.replay` -- the replay ring of the deep sides;
* :mod:`~.repeated` -- Algorithm 1's run on a repeated game (:func:`fit`);
* :mod:`~.episodes` -- the generic loop: any learner object on any PettingZoo
  ``ParallelEnv``.
"""

from cmarlcd.training.episodes import play_episodes
from cmarlcd.training.repeated import FitResult, fit
from cmarlcd.training.tabular import EpisodeStats, TabularRun, evaluate

__all__ = ["EpisodeStats", "FitResult", "TabularRun", "evaluate", "fit", "play_episodes"]
