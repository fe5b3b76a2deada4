"""How learners meet games: one loop per kind of learner, for every game.

* :mod:`~.episodes` -- the generic loop: any learner object on any PettingZoo ``ParallelEnv``;
* :mod:`~.tabular` -- compiled learning and greedy evaluation of any tabular learner;
* :mod:`~.repeated` -- Algorithm 1's run on a repeated game (:func:`fit`);
* :mod:`~.deep` -- seed-batched VDN / QMIX collection and training (``[deep]`` extra);
* :mod:`~.replay` -- replay buffers and their compiled sampling.
"""

from cmarlcd.training.episodes import play_episodes
from cmarlcd.training.repeated import FitResult, fit
from cmarlcd.training.tabular import EpisodeStats, TabularRun, evaluate

__all__ = ["EpisodeStats", "FitResult", "TabularRun", "evaluate", "fit", "play_episodes"]
