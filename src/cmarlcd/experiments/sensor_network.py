"""The distributed sensor network protocol of Section V-A (Tables 3-7, Fig. 4).

The DSN under the learn-then-evaluate protocol of :mod:`cmarlcd.experiments.episodic`:
an evaluation episode succeeds when its return is the optimum, 42, reached in exactly 3
steps; runs store the greedy joint action of the 42 non-terminal states (Fig. 4); the
paper's values come from :mod:`cmarlcd.paper`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from cmarlcd.errors import require
from cmarlcd.experiments.episodic import (
    MAX_POLICY_ENTRIES,
    EpisodicGame,
    EpisodicSweep,
    Options,
    experiment,
    terminated_episodes,
)
from cmarlcd.games import sensor_network as dsn
from cmarlcd.games.sensor_network import sized
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.tabular.automata import AutomatonConfig
from cmarlcd.learners.tabular.coordination import StochasticConfig
from cmarlcd.paper import DSN_EPISODES, dsn_value
from cmarlcd.registry import LearnerConfig
from cmarlcd.training.tabular import EpisodeStats

EXPERIMENT = "dsn"
#: Seeds of one deep config trained together in one stacked model (the runner's batch).
#: [choice] 10: on the 2-core CPU benchmark B = 10 gives the best aggregate env steps/s for
#: VDN (2.8x B = 1) and is within 10 % of B = 50 for QMIX (1.9x against 2.1x), with a fifth
#: of the memory and finer work units for the workers (see benchmarks/bench_deep.py).
SEED_BATCH = 10
PAPER_RUNS = 50
PAPER_EVAL_EPISODES = 50_000
#: The rows of Tables 3-7 a sweep runs unless told otherwise: the tabular learners.
DEFAULT_LEARNERS: tuple[LearnerConfig, ...] = (StochasticConfig(), AutomatonConfig())


def optimal_episodes(stats: EpisodeStats) -> np.ndarray:
    """An episode succeeds when it returns the optimum, 42, in exactly 3 steps."""
    return (stats.returns == dsn.OPTIMAL_RETURN) & (stats.lengths == dsn.OPTIMAL_STEPS)


#: The options a larger sensor network takes (``cmarl-cd dsn --grid 3x4 --targets 3``).
LAYOUT_OPTIONS = ("grid", "targets")


def layout_spec(options: Options) -> GameSpec:
    """The DSN of a layout's options (``grid``, ``targets``; the paper's where not
    given), refused where a table of every state's greedy joint action, which the
    protocol evaluates for a tabular learner, would pass :data:`MAX_POLICY_ENTRIES`."""
    given = dict(options)
    unknown = sorted(set(given) - set(LAYOUT_OPTIONS))
    require(not unknown, unknown[0] if unknown else "game", "is no option of the DSN")
    rows, cols = given.get("grid", sized.PAPER_GRID)
    spec = dsn.make_spec(rows, cols, given.get("targets", sized.PAPER_TARGETS))
    entries = spec.n_states * len(spec.agents)
    require(
        entries <= MAX_POLICY_ENTRIES,
        "targets",
        f"this protocol evaluates a table of every state's joint action, here {entries:,} "
        f"entries, more than {MAX_POLICY_ENTRIES:,}",
    )
    return spec


@functools.lru_cache(maxsize=32)
def larger_network(game: EpisodicGame, options: Options) -> EpisodicGame:
    """The DSN at another size (:func:`cmarlcd.games.sensor_network.make_spec`): an
    episode succeeds when every target is captured within the step cap (the paper's
    success, 42 in 3 steps, is defined at its size only); no policy is stored, and there
    are no paper values."""
    return EpisodicGame(game.experiment, layout_spec(options), terminated_episodes, 0)


DSN_GAME = EpisodicGame(
    experiment=EXPERIMENT,
    spec=dsn.SPEC,
    success=optimal_episodes,
    policy_states=dsn.N_STATES,
    paper_value=dsn_value,
    variant=larger_network,
)


def layout_options(rows: int, cols: int, targets: int) -> Options:
    """The options of a DSN of ``rows`` x ``cols`` cells and ``targets`` targets: none
    for the paper's (so its runs keep their keys)."""
    if (rows, cols, targets) == (*sized.PAPER_GRID, sized.PAPER_TARGETS):
        return ()
    return (("grid", (rows, cols)), ("targets", targets))


DSN = experiment(DSN_GAME)


@dataclass(frozen=True)
class DsnSweep(EpisodicSweep):
    """The DSN protocol; defaults are the paper's (CMARL-CD and LA-OCA, 50 runs, L of
    100k, 300k and 500k episodes, 50,000 evaluation episodes)."""

    game: EpisodicGame = DSN_GAME
    learners: tuple[LearnerConfig, ...] = DEFAULT_LEARNERS
    episodes: tuple[int, ...] = DSN_EPISODES
    runs: int = PAPER_RUNS
    eval_episodes: int = PAPER_EVAL_EPISODES
