"""Learn, then evaluate greedily: the protocol of Section V-A, for any one-team game.

Each run trains a learner on a game and evaluates its fixed greedy joint policy for
``eval_episodes`` episodes after each budget ``L`` of learning episodes, plus a short
evaluation at evenly spaced points for the learning curve. Learners whose schedule does
not depend on ``L`` (the tabular ones) train once to the largest ``L`` and are evaluated
at every checkpoint on the way; those that anneal over ``L`` (VDN, QMIX: eq. 18) make one
run per ``L``. Evaluation draws from its own stream (keyed by ``L``), so a checkpoint's
numbers do not depend on which others were asked for.

A game enters the protocol as an :class:`EpisodicGame` (its spec, what counts as a
successful episode, the paper's values if any); :mod:`cmarlcd.experiments.sensor_network`
is the DSN's. The protocol uses only the public training loops of :mod:`cmarlcd.training`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Self

import numpy as np

from cmarlcd import registry
from cmarlcd.errors import require
from cmarlcd.experiments.episodic_costs import (
    SECONDS_PER_EPISODE,
    episode_scale,
    learn_seconds,
    run_cost,
)
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.config import DeepLearnerConfig
from cmarlcd.limits import (
    MAX_CURVE_POINTS,
    check_at_most,
    check_episodes,
    check_run_count,
    check_seed,
    check_steps,
)
from cmarlcd.policies.keeping import POLICY, wanted
from cmarlcd.policies.learned import evaluated_policy, full_table
from cmarlcd.progress import report_progress, unit_cost
from cmarlcd.registry import LearnerConfig
from cmarlcd.run_logs import log_point, logging
from cmarlcd.runs import (
    Experiment,
    RunRecord,
    RunSpec,
    Settings,
    added_setting,
    identity,
    parse_settings,
)
from cmarlcd.training.deep_kernels import MAX_INDEX_STATES
from cmarlcd.training.greedy import GreedyPolicy
from cmarlcd.training.loop import BUDGET_UNITS
from cmarlcd.training.tabular import EpisodeStats, TabularRun, evaluate

#: [choice] Learning-curve resolution: greedy evaluations at this many evenly spaced
#: points up to the largest L, each over CURVE_EVAL_EPISODES episodes.
CURVE_POINTS = 20
CURVE_EVAL_EPISODES = 2_000
#: [choice] Tables report the population standard deviation over runs (ddof = 0).
STD_DDOF = 0
#: The per-(algorithm, L) quantities of a table row, in the order of the JSON output.
TABLE_METRICS = (
    "success_rate",
    "mean_return",
    "std_return",
    "mean_steps",
    "std_steps",
    "min_return",
    "max_steps",
)


def _no_paper_value(algorithm: str, episodes: int, metric: str) -> float | None:
    return None


#: Further per-episode measures of a checkpoint's evaluation, by name (each stored as the
#: share of episodes it holds for).
Metrics = tuple[tuple[str, Callable[[EpisodeStats], np.ndarray]], ...]
Scalars = Mapping[str, float | None] | None

#: A game's options (e.g. a larger DSN's grid and targets), as sorted (name, value) pairs
#: of JSON values; empty: the game as the paper plays it.
Options = tuple[tuple[str, Any], ...]


def _no_variants(game: EpisodicGame, options: Options) -> EpisodicGame:
    require(not options, "game", f"{game.experiment} takes no options (got {dict(options)})")
    return game


#: [choice] The largest greedy-policy table (states x agents) the protocol evaluates for
#: a tabular learner: 50M int64 entries, 400 MB.
MAX_POLICY_ENTRIES = 50_000_000


def terminated_episodes(stats: EpisodeStats) -> np.ndarray:
    """An episode succeeds when it terminated (every goal met) within the step cap."""
    return stats.terminated


@dataclass(frozen=True)
class EpisodicGame:
    """A one-team game under this protocol.

    Attributes:
        experiment: the store's experiment name of its runs.
        spec: the game.
        success: per-episode success from the evaluation's episodes.
        policy_states: the states whose greedy joint action a run stores (the first ones).
        paper_value: the paper's published value of a metric, if any.
        variant: the game with some options (e.g. a larger DSN): ``variant(game, options)``.
        also: further shares of episodes a checkpoint's evaluation stores (e.g. the
            paper's success where a study's own is another).
    """

    experiment: str
    spec: GameSpec
    success: Callable[[EpisodeStats], np.ndarray]
    policy_states: int
    paper_value: Callable[[str, int, str], float | None] = _no_paper_value
    variant: Callable[[EpisodicGame, Options], EpisodicGame] = _no_variants
    also: Metrics = ()

    def with_options(self, options: Options) -> EpisodicGame:
        """The game with ``options`` (itself when there are none)."""
        return self.variant(self, options) if options else self


def anneals_over_budget(config: LearnerConfig) -> bool:
    """Whether a learner's schedule depends on its learning budget L (eq. 18's ε)."""
    return isinstance(config, DeepLearnerConfig) and config.anneals


def is_deep(config: LearnerConfig) -> bool:
    """Whether a learner trains networks (its seeds then learn as one stacked model)."""
    return isinstance(config, DeepLearnerConfig)


@dataclass(frozen=True)
class EpisodicRun(Settings):
    """One learner's runs: trained to the largest checkpoint, its greedy policy
    evaluated for ``eval_episodes`` episodes at every checkpoint and for
    ``curve_eval_episodes`` at ``curve_points`` evenly spaced budgets (the curve)."""

    learner: LearnerConfig
    checkpoints: tuple[int, ...]
    """The budgets L evaluated for the tables, sorted, each once."""
    eval_episodes: int
    curve_points: int
    curve_eval_episodes: int
    options: Options = ()
    """The game's options (stored under ``"game"`` only when there are some)."""
    unit: str = "episodes"
    """What the budgets count: learning episodes, or environment ``"steps"`` (stored
    only then; a budget of steps ends at the end of the episode it is reached in)."""
    eval_at_start: bool = added_setting(False, "0.7.0")
    """[choice] Whether the curve has a point at budget 0 too, the greedy policy before
    any learning (EPyMARL's protocol evaluates there; stored only when on)."""

    def to_config(self) -> dict[str, Any]:
        config = {
            "algorithm": self.learner.name,
            "checkpoints": list(self.checkpoints),
            "eval_episodes": self.eval_episodes,
            "curve_points": self.curve_points,
            "curve_eval_episodes": self.curve_eval_episodes,
            "learner": identity(self.learner),
        }
        if self.options:
            config["game"] = dict(self.options)
        if self.unit != "episodes":
            config["unit"] = self.unit
        if self.eval_at_start:
            config["eval_at_start"] = True
        return config

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> Self:
        return cls(
            registry.learner_config(config["algorithm"], config["learner"]),
            tuple(config["checkpoints"]),
            config["eval_episodes"],
            config["curve_points"],
            config["curve_eval_episodes"],
            options_of(config.get("game", {})),
            config.get("unit", "episodes"),
            config.get("eval_at_start", False),
        )

    def stream(self) -> dict[str, Any]:
        """The learner, the game's options, and L for a learner that anneals over it:
        the evaluation settings do not change what a run learns."""
        stream: dict[str, Any] = {"algorithm": self.learner.name, "learner": identity(self.learner)}
        if self.options:
            stream["game"] = dict(self.options)
        if self.unit != "episodes":
            stream["unit"] = self.unit
        if anneals_over_budget(self.learner):
            stream["episodes"] = self.checkpoints[0]
        return stream

    @property
    def largest(self) -> int:
        """The learning budget: the largest checkpoint."""
        return max(self.checkpoints)

    def schedule(self) -> list[int]:
        """Every budget at which a run stops to evaluate: checkpoints and curve points."""
        points = self.curve_points
        curve = (
            {round(self.largest * k / points) for k in range(1, points + 1)} if points else set()
        )
        start = {0} if self.eval_at_start else set()
        return sorted(curve | set(self.checkpoints) - {0} | start)

    def work(self, max_steps: int = 1) -> float:
        """The episodes one run plays (learning and evaluation): its progress units. A
        budget of steps counts as episodes of ``max_steps`` steps (the game's cap)."""
        evaluated = self.schedule()
        if anneals_over_budget(self.learner) and not self.eval_at_start:
            evaluated = [b for b in evaluated if b > 0]  # reached by playing, never at 0
        curve = self.curve_eval_episodes * len(evaluated)
        return self.learned(max_steps) + curve + self.eval_episodes * len(self.checkpoints)

    def learned(self, max_steps: int) -> float:
        """The learning budget in episodes (one of ``max_steps`` steps per episode where
        it counts steps: the unit a run's progress reports its learning in)."""
        return self.largest / max_steps if self.unit == "steps" else self.largest


def options_of(options: Mapping[str, Any]) -> Options:
    """Options as settings keep them: sorted pairs, lists as tuples."""
    return tuple(
        (name, tuple(value) if isinstance(value, list) else value)
        for name, value in sorted(options.items())
    )


def run_of(record: RunRecord) -> EpisodicRun:
    """The settings of a stored run."""
    return parse_settings(EpisodicRun, record.key.config)  # type: ignore[return-value]


@dataclass(frozen=True)
class EpisodicSweep:
    """Learners × runs on one game, each evaluated after every budget in ``episodes``."""

    game: EpisodicGame
    learners: tuple[LearnerConfig, ...]
    """The learners to run, each with its settings (see :mod:`cmarlcd.registry`)."""
    episodes: tuple[int, ...]
    runs: int
    eval_episodes: int
    seed: int = 0
    curve_points: int = CURVE_POINTS
    curve_eval_episodes: int = CURVE_EVAL_EPISODES
    options: Options = ()
    """The game's options (e.g. a larger DSN's ``grid`` and ``targets``)."""
    unit: str = "episodes"
    """What ``episodes`` counts: learning episodes, or environment ``"steps"``."""
    eval_at_start: bool = False
    """Whether the curve has a point at budget 0 (:attr:`EpisodicRun.eval_at_start`)."""

    def __post_init__(self) -> None:
        spec = self.game.with_options(self.options).spec  # refuses options it does not take
        require(self.unit in BUDGET_UNITS, "unit", f"must be one of {BUDGET_UNITS}")
        require(len(self.learners) > 0, "algorithms", "needs at least one algorithm")
        deep = [c.name for c in self.learners if is_deep(c)]
        require(
            not deep or spec.n_features > 0 or spec.n_states <= MAX_INDEX_STATES,
            "algorithms",
            f"{', '.join(deep)} read one-hot state indices where a game has no features, "
            f"at most {MAX_INDEX_STATES:,} states ({spec.name} has {spec.n_states:,})",
        )
        names = [config.name for config in self.learners]
        require(len(set(names)) == len(names), "algorithms", f"each at most once (got {names})")
        require(len(self.episodes) > 0, "episodes", "needs at least one budget")
        budget = "steps" if self.unit == "steps" else "episodes"
        require(min(self.episodes) >= 1, budget, f"must be >= 1 (got {min(self.episodes)})")
        if self.unit == "steps":
            check_steps(max(self.episodes), "steps")
        else:
            check_episodes(max(self.episodes), "episodes")
        require(self.runs >= 1, "runs", f"must be >= 1 (got {self.runs})")
        require(
            self.eval_episodes >= 1, "eval_episodes", f"must be >= 1 (got {self.eval_episodes})"
        )
        check_episodes(self.eval_episodes, "eval_episodes")
        check_seed(self.seed)
        require(self.curve_points >= 0, "curve_points", f"must be >= 0 (got {self.curve_points})")
        check_at_most(self.curve_points, MAX_CURVE_POINTS, "curve_points")
        require(
            self.curve_eval_episodes >= 1,
            "curve_eval_episodes",
            f"must be >= 1 (got {self.curve_eval_episodes})",
        )
        check_episodes(self.curve_eval_episodes, "curve_eval_episodes")
        check_run_count(self.run_count())

    def run_count(self) -> int:
        """Runs of the sweep, without listing them: one per learner and run, times the
        budgets for a learner that anneals over L."""
        budgets = len(set(self.episodes))
        per_learner = [budgets if anneals_over_budget(c) else 1 for c in self.learners]
        return sum(per_learner) * self.runs

    @property
    def algorithms(self) -> tuple[str, ...]:
        return tuple(config.name for config in self.learners)

    def settings(self, learner: LearnerConfig, budgets: Sequence[int] | None = None) -> EpisodicRun:
        """The settings of one learner's runs (evaluated after each budget)."""
        return EpisodicRun(
            learner,
            tuple(sorted(set(budgets or self.episodes))),
            self.eval_episodes,
            self.curve_points,
            self.curve_eval_episodes,
            self.options,
            self.unit,
            self.eval_at_start,
        )

    def specs(self) -> list[RunSpec]:
        """One spec per (learner, run), trained once to the largest L, with streams that
        depend on the learner only; for learners that anneal over L, one spec per
        (learner, L, run), streams depending on the learner and L."""
        specs = []
        for learner in self.learners:
            budgets = sorted(set(self.episodes))
            groups = [[b] for b in budgets] if anneals_over_budget(learner) else [None]
            for group in groups:
                settings = self.settings(learner, group)
                specs += [
                    RunSpec.make(self.game.experiment, learner.name, settings, self.seed, r)
                    for r in range(self.runs)
                ]
        return specs


# ------------------------------------------------------------------------- runs


def keyed_rng(seed: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """A stream that depends only on ``seed`` and ``key`` (e.g. an evaluation at L)."""
    child = np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, *key))
    return np.random.default_rng(child)


class Recorder:
    """Evaluates a run's greedy policy at each budget: the checkpoints with
    ``eval_episodes`` episodes, every budget with ``curve_eval_episodes`` for the curve."""

    def __init__(self, game: EpisodicGame, settings: EpisodicRun, eval_seed, index: int = 0):
        self.scale = episode_scale(game, settings)
        game = game.with_options(settings.options)
        self.game, self.settings, self.eval_seed, self.index = game, settings, eval_seed, index
        self.checkpoints: dict[str, dict[str, float]] = {}
        self.curve: list[list[float]] = []
        self.policy: np.ndarray | None = None
        self.start = time.perf_counter()

    def __call__(self, budget: int, policy: GreedyPolicy, also: Scalars = None) -> None:
        settings = self.settings
        if budget in settings.checkpoints:
            rng = keyed_rng(self.eval_seed, 0, budget)
            found = self._evaluate(policy, settings.eval_episodes, rng, self.game.also)
            self.checkpoints[str(budget)] = found
        rng = keyed_rng(self.eval_seed, 1, budget)
        point = self._evaluate(policy, settings.curve_eval_episodes, rng)
        point_row = [budget, point["success_rate"], point["mean_return"], point["mean_steps"]]
        self.curve.append(point_row)
        found = {"eval/return": point["mean_return"], "eval/success": point["success_rate"],
                 "eval/episode_steps": point["mean_steps"], **(also or {})}  # fmt: skip
        log_point(self.index, budget, found, settings.unit)  # the live curves (--log-dir)
        self.policy = policy.table

    def _evaluate(
        self, policy: GreedyPolicy, episodes: int, rng, also: Metrics = ()
    ) -> dict[str, float]:
        stats = policy.evaluate(episodes, rng)
        with unit_cost(SECONDS_PER_EPISODE * self.scale):
            report_progress(episodes)
        found = {
            "success_rate": int(self.game.success(stats).sum()) / episodes,
            "mean_return": float(stats.returns.sum()) / episodes,
            "mean_steps": int(stats.lengths.sum()) / episodes,
        }
        return found | {name: int(rule(stats).sum()) / episodes for name, rule in also}

    def metrics(self) -> dict[str, Any]:
        table = [] if self.policy is None else self.policy[: self.game.policy_states].tolist()
        return {
            "checkpoints": self.checkpoints,
            "curve": self.curve,
            "policy": table,
            "seconds": time.perf_counter() - self.start,
        }


def run(game: EpisodicGame, settings: EpisodicRun, seed: np.random.SeedSequence) -> dict[str, Any]:
    """One run: train to each budget in turn, evaluating the greedy policy at each."""
    learner = settings.learner
    if is_deep(learner):
        return run_batch(game, settings, [seed])[0]
    env_seed, agent_seed, eval_seed = seed.spawn(3)
    spec = game.with_options(settings.options).spec
    training = TabularRun(
        spec, learner, np.random.default_rng(env_seed), np.random.default_rng(agent_seed)
    )
    record, trained = Recorder(game, settings, eval_seed), 0
    for budget in settings.schedule():
        if settings.unit == "steps":  # to the end of the episode the budget is reached in
            before = training.turns
            training.train_until_steps(budget)
            learned = (training.turns - before) / spec.max_steps
        else:
            training.train(budget - trained)
            learned = budget - trained
        with unit_cost(learn_seconds(learner) * record.scale):
            report_progress(learned)
        trained = budget
        record(budget, GreedyPolicy(spec, table=training.greedy_policy()))
    metrics = record.metrics()
    if wanted() and record.policy is not None:  # --save-policies: the final greedy table
        meta = {"inputs": "state", "game": game.experiment}
        metrics[POLICY] = full_table(record.policy, spec.action_counts, meta)
    return metrics


def run_batch(
    game: EpisodicGame, settings: EpisodicRun, seeds: list[np.random.SeedSequence]
) -> list[dict[str, Any]]:
    """Runs of one deep learner's settings, all seeds trained together in one stacked
    model."""
    from cmarlcd.training.deep import DeepBatch  # needs the [deep] extra

    train_seeds, eval_seeds = zip(*(s.spawn(2) for s in seeds), strict=True)
    records = [Recorder(game, settings, e, k) for k, e in enumerate(eval_seeds)]
    learner = settings.learner
    spec = game.with_options(settings.options).spec
    batch = DeepBatch(spec, learner, train_seeds, settings.largest, unit=settings.unit)
    kept: list[Any] = [None] * len(seeds)
    meta = {"inputs": "state", "game": game.experiment}

    def evaluate(k: int, budget: int, policy: GreedyPolicy) -> None:
        records[k](budget, policy, batch.scalars(k) if logging() else None)
        if wanted():  # --save-policies: the latest evaluation's policy (the last stays)
            kept[k] = evaluated_policy(policy, spec.action_counts, meta)

    with unit_cost(learn_seconds(learner) * records[0].scale):  # evaluations say their own
        # a budget 0 (a curve's rounding can give one) is evaluated only where asked for,
        # as before eval_at_start existed
        schedule = [b for b in settings.schedule() if b > 0 or settings.eval_at_start]
        batch.train(schedule, evaluate)
    results = [r.metrics() for r in records]
    for metrics, policy in zip(results, kept, strict=True):
        if policy is not None:
            metrics[POLICY] = policy
    return results


def warm_up(game: EpisodicGame) -> None:
    """Compile the tabular loops for ``game`` (once, before workers fork)."""
    for config in registry.LEARNERS.values():
        if not is_deep(config):
            rngs = np.random.default_rng(0), np.random.default_rng(1)
            training = TabularRun(game.spec, config, *rngs)
            training.train(2)
            evaluate(game.spec, training.greedy_policy(), 2, np.random.default_rng(2))


def experiment(game: EpisodicGame) -> Experiment:
    """The runner's view of ``game`` under this protocol."""
    return Experiment(
        game.experiment,
        EpisodicRun,
        run=lambda settings, seed: run(game, settings, seed),
        warm_up=lambda: warm_up(game),
        cost=lambda settings: run_cost(game, settings),
        run_batch=lambda settings, seeds: run_batch(game, settings, seeds),
        batchable=lambda settings: is_deep(settings.learner),
        work=lambda settings: settings.work(game.with_options(settings.options).spec.max_steps),
        work_unit="episodes",
        uses_device=lambda settings: is_deep(settings.learner),
        keeps_policies=lambda settings: True,
    )
