"""Where tables stop: learners against the size of the sensor network (beyond the paper).

The paper's future work is to "incorporate deep learning into CMARL-CD to improve
scalability". This study measures what that buys: tabular CMARL-CD, deep CMARL-CD, VDN,
QMIX and the classic learner that does best on the paper's DSN, each learning the DSN at
several sizes (R x C cells, K targets: :func:`cmarlcd.games.sensor_network.make_spec`)
under one budget, and evaluated greedily as in Section V-A
(:mod:`cmarlcd.experiments.episodic`). At every size, a run's success is the share of
evaluation episodes in which every target is captured within the step cap; at the
paper's size, its own success (return 42 in 3 steps) is stored beside it.

Every size is played by the generic layout, so the deep learners read the same state
features (target cells and captured flags) at every size, the paper's included, where
the ``dsn`` command's deep learners read its 43 states one-hot; the tabular learners
play the paper's size bit for bit as ``dsn`` does.
"""

from __future__ import annotations

import functools
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.errors import ConfigError, require
from cmarlcd.experiments.episodic import (
    STD_DDOF,
    EpisodicGame,
    EpisodicSweep,
    Options,
    experiment,
    run_of,
    terminated_episodes,
)
from cmarlcd.experiments.episodic_results import row_label
from cmarlcd.experiments.sensor_network import layout_spec, optimal_episodes
from cmarlcd.games.sensor_network import sized
from cmarlcd.limits import check_run_count
from cmarlcd.registry import LearnerConfig
from cmarlcd.runs import RunRecord, RunSpec

EXPERIMENT = "scaling"

#: A network's size: rows and columns of cells, and targets.
Size = tuple[int, int, int]

PAPER_SIZE: Size = (*sized.PAPER_GRID, sized.PAPER_TARGETS)
#: [choice] From the paper's network (43 states) to one of more than 10^5 states, about a
#: decade and a half apart: 2x3/2 (43 states, 12 sensors), 3x4/3 (1,753; 20), 4x4/4
#: (58,625; 25), 4x5/4 (146,001; 30).
DEFAULT_SIZES: tuple[Size, ...] = ((2, 3, 2), (3, 4, 3), (4, 4, 4), (4, 5, 4))
#: [choice] The classic learner of ``cmarl-cd compare`` with the best success on the
#: paper's DSN (distributed Q, 2 %; hysteretic 1 %, IQL and lenient 0 %).
CLASSIC_LEARNER = "distributed-q"
DEFAULT_LEARNER_NAMES = ("cmarl-cd", "deep-cmarl-cd", "vdn", "qmix", CLASSIC_LEARNER)
#: [choice] The default budget, one L for every size and learner (fits an hour on 2 cores
#: with the defaults below: docs, "Where tables stop").
DEFAULT_EPISODES = 20_000
DEFAULT_RUNS = 3
DEFAULT_EVAL_EPISODES = 2_000
#: [choice] A short learning curve per run: greedy evaluations at 5 points, 200 episodes each.
CURVE_POINTS = 5
CURVE_EVAL_EPISODES = 200


def size_options(size: Size) -> Options:
    """The options of a network of ``size``: always given, the paper's size included."""
    rows, cols, targets = size
    return (("grid", (rows, cols)), ("targets", targets))


def size_of(options: Options) -> Size:
    """The size a run's options give."""
    given = dict(options)
    rows, cols = given["grid"]
    return (rows, cols, given["targets"])


def size_label(size: Size) -> str:
    """``"3x4/3"``: cells, then targets."""
    return f"{size[0]}x{size[1]}/{size[2]}"


@functools.lru_cache(maxsize=32)
def network(game: EpisodicGame, options: Options) -> EpisodicGame:
    """The network of ``options``; at the paper's size, the paper's success is stored too."""
    also = (("paper_success", optimal_episodes),) if size_of(options) == PAPER_SIZE else ()
    return EpisodicGame(game.experiment, layout_spec(options), terminated_episodes, 0, also=also)


SCALING_GAME = EpisodicGame(
    experiment=EXPERIMENT,
    spec=sized.make_spec(*PAPER_SIZE),
    success=terminated_episodes,
    policy_states=0,
    variant=network,
)
SCALING = experiment(SCALING_GAME)


def default_learners() -> tuple[LearnerConfig, ...]:
    """The study's learners with their defaults."""
    return tuple(registry.require_learner(name) for name in DEFAULT_LEARNER_NAMES)


@dataclass(frozen=True)
class ScalingStudy:
    """Learners x sizes x runs, each run learning for ``episodes`` episodes."""

    sizes: tuple[Size, ...] = DEFAULT_SIZES
    learners: tuple[LearnerConfig, ...] = ()
    """The learners (default: :data:`DEFAULT_LEARNER_NAMES`)."""
    episodes: int = DEFAULT_EPISODES
    runs: int = DEFAULT_RUNS
    eval_episodes: int = DEFAULT_EVAL_EPISODES
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.learners:
            object.__setattr__(self, "learners", default_learners())
        require(len(self.sizes) > 0, "sizes", "needs at least one size")
        require(len(set(self.sizes)) == len(self.sizes), "sizes", "each at most once")
        check_run_count(len(self.sizes) * len(self.learners) * self.runs)
        for size in self.sizes:  # every size checked before anything runs, named as given
            try:
                layout_spec(size_options(size))
            except ConfigError as error:
                raise ConfigError("sizes", f"{size_label(size)}: {error.message}") from None
        self.sweeps()  # and every setting

    @functools.cache  # noqa: B019  (a frozen study: its sweeps do not change)
    def sweeps(self) -> tuple[EpisodicSweep, ...]:
        """One learn-then-evaluate sweep per size."""
        return tuple(
            EpisodicSweep(
                game=SCALING_GAME,
                learners=self.learners,
                episodes=(self.episodes,),
                runs=self.runs,
                eval_episodes=self.eval_episodes,
                seed=self.seed,
                curve_points=CURVE_POINTS,
                curve_eval_episodes=CURVE_EVAL_EPISODES,
                options=size_options(size),
            )
            for size in self.sizes
        )

    def specs(self) -> list[RunSpec]:
        """Every run of every size, smallest size first."""
        return [spec for sweep in self.sweeps() for spec in sweep.specs()]


# --------------------------------------------------------------------- results


@dataclass(frozen=True)
class ScalingRow:
    """One learner at one size, over its runs (mean and population std over runs)."""

    size: str
    states: int
    sensors: int
    algorithm: str
    label: str
    episodes: int
    runs: int
    success_rate: float
    std_success: float
    return_per_target: float
    mean_steps: float
    paper_success: float | None
    """The paper's success (42 in 3 steps), at the paper's size only."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def summarize(records: Iterable[RunRecord]) -> list[ScalingRow]:
    """One row per (size, learner and settings, L), smallest size first."""
    cells: dict[tuple[Size, str, str, int], list[dict[str, float]]] = defaultdict(list)
    for rec in records:
        settings = run_of(rec)
        key = (size_of(settings.options), rec.key.algorithm, row_label(settings.learner))
        for budget, result in rec.metrics["checkpoints"].items():
            cells[(*key, int(budget))].append(result)
    order = list(registry.LEARNERS)
    rows = []
    for (size, name, label, budget), results in sorted(
        cells.items(), key=lambda item: (_states(item[0][0]), _rank(order, item[0][1]), item[0])
    ):
        rows.append(_row(size, name, label, budget, results))
    return rows


def _rank(order: Sequence[str], name: str) -> int:
    return order.index(name) if name in order else len(order)


def _spec(size: Size):
    """The network of ``size`` (the cached game the runs played)."""
    return network(SCALING_GAME, size_options(size)).spec


def _states(size: Size) -> int:
    return _spec(size).n_states


def _row(
    size: Size, name: str, label: str, budget: int, results: list[dict[str, float]]
) -> ScalingRow:
    spec = _spec(size)
    success = np.array([r["success_rate"] for r in results])
    paper = [r["paper_success"] for r in results if "paper_success" in r]
    return ScalingRow(
        size=size_label(size),
        states=spec.n_states,
        sensors=spec.n_agents,
        algorithm=name,
        label=label,
        episodes=budget,
        runs=len(results),
        success_rate=float(success.mean()),
        std_success=float(success.std(ddof=STD_DDOF)),
        return_per_target=float(np.mean([r["mean_return"] for r in results])) / size[2],
        mean_steps=float(np.mean([r["mean_steps"] for r in results])),
        paper_success=float(np.mean(paper)) if paper else None,
    )


def protocol_key(record: RunRecord) -> tuple:
    """Runs that belong in one study: same seed, budget and evaluation."""
    settings = run_of(record)
    return (record.key.root_seed, settings.checkpoints, settings.eval_episodes)
