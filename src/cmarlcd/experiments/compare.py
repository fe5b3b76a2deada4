"""Beyond the paper: CMARL-CD against the classic independent learners on the games that
made their names, and on the DSN.

Each run plays one learner on one game for a budget of games and records whether the
greedy joint action it ends on is optimal (by expected payoff, for stochastic payoffs)
and when that greedy joint action last changed (*settled*). The games are the climbing
game, the penalty game for several ``k``, the partially and fully stochastic climbing
games (Kapetanakis & Kudenko 2002), and the random games of Tables 1-2 at their sizes
(a fresh game per run; every learner meets the same games: a random game's run is
seeded by the family and size alone, :meth:`CompareRun.stream`). On the DSN (a
stochastic game) the learners that have a stochastic form (CMARL-CD's Algorithm 2, IQL,
distributed Q, hysteretic, lenient; FMQ and JAL are defined for repeated games only) run
the DSN protocol of :mod:`cmarlcd.experiments.sensor_network` at :data:`DSN_EPISODES`
learning episodes; its column is the greedy policy's success rate.

[choice] Every learner gets the same budget, ``max(MIN_GAMES, GAMES_PER_JOINT_ACTION ·
|A|)`` games for ``|A|`` joint actions; CMARL-CD stops earlier when its strategies are
pure (its own stopping rule), the classic learners play the whole budget. The classic
learners keep their papers' exploration schedules, which were tuned on 3 × 3 games.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, Self

import numpy as np

from cmarlcd import registry
from cmarlcd.compiled import specialise
from cmarlcd.errors import require
from cmarlcd.experiments import episodic, episodic_results
from cmarlcd.experiments.sensor_network import DSN_GAME, DsnSweep
from cmarlcd.learners.deep.config import DeepLearnerConfig
from cmarlcd.learners.tabular import joint_action
from cmarlcd.limits import check_episodes, check_run_count, check_seed
from cmarlcd.policies.keeping import POLICY, wanted
from cmarlcd.policies.learned import full_table
from cmarlcd.run_logs import log_point
from cmarlcd.runs import Experiment, RunRecord, RunSpec, Settings, identity, parse_settings
from cmarlcd.training.greedy import GreedyPolicy
from cmarlcd.training.repeated import play_watching_greedy

EXPERIMENT = "compare"
#: [choice] The budget of games of a run: at least this many ...
MIN_GAMES = 5_000
#: ... and this many per joint action of the game.
GAMES_PER_JOINT_ACTION = 10
DEFAULT_RUNS = 50
#: [choice] The DSN column: learning episodes L and greedy evaluation episodes per run.
DSN_EPISODES = 100_000
DSN_EVAL_EPISODES = 10_000
#: The name of the DSN column.
DSN = "dsn"

#: The games of the comparison, in column order (the registry's games with a repeated
#: form; the DSN column is :data:`DSN`).
GAMES: dict[str, registry.Game] = registry.repeated_games()


@dataclass(frozen=True)
class CompareRun(Settings):
    """One learner on one game of the comparison (a random game's size), for ``budget``
    games; the learner's settings are stored flat beside the game's."""

    game: str
    learner: Any
    """The learner's settings (a repeated-game learner of :mod:`cmarlcd.registry`, or a
    deep learner's one-step preset)."""
    budget: int
    size: registry.Size | None = None
    """(agents, actions) of a random game; None for a fixed one."""

    def to_config(self) -> dict[str, Any]:
        where = {} if self.size is None else {"agents": self.size[0], "actions": self.size[1]}
        return {
            "game": self.game,
            **where,
            "budget": self.budget,
            "learner": self.learner.name,
            **identity(self.learner),
        }

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> Self:
        size = (config["agents"], config["actions"]) if "agents" in config else None
        learner = registry.comparable_learner(config["learner"], config)
        return cls(config["game"], learner, config["budget"], size)

    def stream(self) -> dict[str, Any] | None:
        """A random game's run is seeded by the game alone (family and size), so every
        learner meets the same games run for run (common random numbers); a fixed
        game's run by its whole config, the learner's settings included."""
        if self.size is None:
            return None
        return {"game": self.game, "agents": self.size[0], "actions": self.size[1]}


def compare_run_of(record: RunRecord) -> CompareRun:
    """The settings of a stored run of the comparison's repeated games."""
    return parse_settings(CompareRun, record.key.config)  # type: ignore[return-value]


def budget(joint_actions: int) -> int:
    """The games of one run on a game of ``joint_actions`` joint actions."""
    return max(MIN_GAMES, GAMES_PER_JOINT_ACTION * joint_actions)


#: The learners whose tables span the joint actions: they play small games only.
JOINT_LEARNERS = (joint_action.JointActionConfig.name, joint_action.CentralQConfig.name)


def plays(learner: str, joint_actions: int) -> bool:
    """Whether ``learner`` plays a game that size (JAL, central Q and [choice] the deep
    learners, whose gradient steps make a game a thousand times dearer, only small ones)."""
    small_only = learner in JOINT_LEARNERS or registry.needs_torch(learner)
    return not small_only or joint_actions <= joint_action.MAX_JOINT_ACTIONS


def changed_settings(learner: Any) -> dict[str, Any]:
    """The settings where ``learner`` differs from the way ``compare`` plays it by
    default (what ``--set`` changed)."""
    default = registry.comparable_learners()[learner.name]
    return {
        f.name: getattr(learner, f.name)
        for f in fields(learner)
        if getattr(learner, f.name) != getattr(default, f.name)
    }


def with_changes(learner: Any, changes: dict[str, Any]) -> Any:
    """``learner`` with those of ``changes`` that are its settings."""
    own = {f.name for f in fields(learner)}
    return replace(learner, **{k: v for k, v in changes.items() if k in own})


@dataclass(frozen=True)
class Comparison:
    """Learners × games × runs (random games: runs per size)."""

    learners: tuple[Any, ...]
    games: tuple[str, ...]
    runs: int = DEFAULT_RUNS
    seed: int = 0
    dsn_episodes: int = DSN_EPISODES
    dsn_eval_episodes: int = DSN_EVAL_EPISODES

    def __post_init__(self) -> None:
        require(len(self.learners) > 0, "learners", "needs at least one learner")
        names = [config.name for config in self.learners]
        require(len(set(names)) == len(names), "learners", f"each at most once (got {names})")
        require(len(self.games) > 0, "games", "needs at least one game")
        known = (*GAMES, DSN)
        for name in self.games:
            require(name in known, "games", f"unknown {name!r}; available: {', '.join(known)}")
        require(len(set(self.games)) == len(self.games), "games", "each at most once")
        require(self.runs >= 1, "runs", f"must be >= 1 (got {self.runs})")
        check_seed(self.seed)
        check_episodes(self.dsn_episodes, "dsn_episodes")
        check_episodes(self.dsn_eval_episodes, "dsn_eval_episodes")
        check_run_count(self.run_count())

    def run_count(self) -> int:
        """Runs of the comparison, without listing them (its cells are listed; a cell
        holds ``runs`` runs)."""
        dsn = (DSN in self.games) * len(self.dsn_learners())
        return (len(self.cells()) + dsn) * self.runs

    def cells(self) -> list[CompareRun]:
        """Every cell a learner plays: (learner, game, size)."""
        out = []
        for name in self.games:
            if name == DSN:
                continue
            game = GAMES[name]
            for size in game.sizes or (None,):
                joint_actions = game.joint_actions(size)
                out += [
                    CompareRun(name, learner, budget(joint_actions), size)
                    for learner in self.learners
                    if plays(learner.name, joint_actions)
                ]
        return out

    def specs(self) -> list[RunSpec]:
        """Every run: the repeated games' and the DSN's (experiment ``dsn``)."""
        repeated = [
            RunSpec.make(EXPERIMENT, cell.learner.name, cell, self.seed, r)
            for cell in self.cells()
            for r in range(self.runs)
        ]
        sweep = self.dsn_sweep()
        return repeated + (sweep.specs() if sweep is not None else [])

    def dsn_learners(self) -> tuple[Any, ...]:
        """The chosen learners that have a stochastic form, with their DSN settings and
        the settings where the chosen ones differ from compare's defaults (``--set``)."""
        return tuple(
            with_changes(registry.LEARNERS[c.name], changed_settings(c))
            for c in self.learners
            if c.name in registry.LEARNERS
        )

    def dsn_sweep(self) -> DsnSweep | None:
        """The DSN runs of the comparison, if the DSN is one of its games."""
        learners = self.dsn_learners()
        if DSN not in self.games or not learners:
            return None
        return DsnSweep(
            learners=learners,
            episodes=(self.dsn_episodes,),
            runs=self.runs,
            eval_episodes=self.dsn_eval_episodes,
            seed=self.seed,
            curve_points=0,
        )

    def skipped(self) -> list[tuple[str, str]]:
        """(learner, game) pairs the learner does not play, or not at every size."""
        out = []
        if DSN in self.games:
            stochastic = {c.name for c in self.dsn_learners()}
            out += [(c.name, DSN) for c in self.learners if c.name not in stochastic]
        for name in self.games:
            if name == DSN:
                continue
            game = GAMES[name]
            for learner in self.learners:
                if not all(
                    plays(learner.name, game.joint_actions(s)) for s in game.sizes or (None,)
                ):
                    out.append((learner.name, name))
        return out


def is_comparison_dsn_run(record: RunRecord) -> bool:
    """Whether a stored DSN run is one of a comparison's: one L and no learning curve
    (the paper's protocol draws one)."""
    settings = episodic.run_of(record)
    return len(settings.checkpoints) == 1 and settings.curve_points == 0 and not settings.options


def run_compare(cell: CompareRun, seed: np.random.SeedSequence) -> dict[str, Any]:
    """One run: the game (fresh if random), the learner, the budget; the greedy joint
    action's optimality and the game it settled at."""
    game_seed, env_seed, learner_seed = seed.spawn(3)
    make = GAMES[cell.game].make
    assert make is not None
    game = make(cell.size, np.random.default_rng(game_seed))
    if isinstance(cell.learner, DeepLearnerConfig):
        return _run_deep(cell, game, learner_seed)
    learner = cell.learner
    spec = game.spec()
    counts = spec.action_counts.copy()
    greedy = np.zeros(counts.shape[0], dtype=np.int64)
    loop = specialise(play_watching_greedy, game=spec.kernels, learner=learner.kernels)
    games, converged, settled = loop(
        game.new_env(),
        learner.new_tables(counts),
        learner.params(),
        counts,
        int(cell.budget),
        np.random.default_rng(env_seed),
        np.random.default_rng(learner_seed),
        greedy,
    )
    joint = tuple(int(a) for a in greedy)
    return kept({
        "optimal": bool(game.is_optimal(joint)),
        "greedy_payoff": game.payoff(joint),
        "max_payoff": game.max_payoff,
        "games": int(games),
        "settled": int(settled),
        "converged": bool(converged),
    }, joint, counts)  # fmt: skip


def kept(metrics: dict[str, Any], joint: tuple[int, ...], counts: Any) -> dict[str, Any]:
    """``metrics`` with the run's greedy joint action as its policy where it keeps one
    (``--save-policies``: a table of the game's one state), its payoff in its live
    curves (``--log-dir``)."""
    log_point(0, metrics["games"], {"eval/greedy_payoff": metrics["greedy_payoff"],
              "eval/optimal": float(metrics["optimal"])}, "episodes")  # fmt: skip
    if wanted():
        meta = {"inputs": "state", "game": EXPERIMENT}
        metrics[POLICY] = full_table(np.array([joint], np.int64), counts, meta)
    return metrics


def _run_deep(cell: CompareRun, game: Any, seed: np.random.SeedSequence) -> dict[str, Any]:
    """A deep learner on the repeated game as a one-state stochastic game of one-step
    episodes (:class:`cmarlcd.training.deep.DeepBatch`), for the whole budget (it has no
    stopping rule); its greedy joint action changes at gradient steps only, so it is read
    every ``train_every`` games, and "settled" is the last such game it changed at."""
    from cmarlcd.training.deep import DeepBatch  # needs the [deep] extra

    every = cell.learner.train_every
    batch = DeepBatch(game.spec(), cell.learner, [seed], cell.budget)
    seen: list[tuple[int, tuple[int, ...]]] = []

    def watch(k: int, games: int, policy: GreedyPolicy) -> None:
        assert policy.table is not None  # one state, read one-hot
        seen.append((games, tuple(int(a) for a in policy.table[0])))

    batch.train(range(every, cell.budget + 1, every), watch)
    seen.sort()
    joint = seen[-1][1]
    settled = max((g for (g, j), (_, before) in zip(seen[1:], seen, strict=False) if j != before),
                  default=seen[0][0])  # fmt: skip
    return kept({
        "optimal": bool(game.is_optimal(joint)),
        "greedy_payoff": game.payoff(joint),
        "max_payoff": game.max_payoff,
        "games": cell.budget,
        "settled": int(settled),
        "converged": False,
    }, joint, game.spec().action_counts)  # fmt: skip


def _warm_up() -> None:
    """Compile every learner's loop on deterministic and stochastic payoffs (a few games
    each)."""
    for game in ("climbing", "climbing-ps"):
        for name in registry.REPEATED_LEARNERS:
            learner = registry.repeated_learner(name)
            run_compare(CompareRun(game, learner, 10), np.random.SeedSequence(0))


#: Estimated seconds per game and agent-action of each learner (CMARL-CD usually stops
#: long before its budget), and the joint-action learners' per game, agent and joint
#: action (they sum over the joint actions every game): fitted to the quick preset's
#: measured runs on the project's 2-core machine (benchmarks/fit_costs.py).
SECONDS_PER_GAME_ACTION = {
    "deep-cmarl-cd": 1.5e-5,
    "cmarl-cd": 6e-10,
    "iql": 2.9e-8,
    "hysteretic": 2.6e-8,
    "fmq": 3.8e-8,
    "lenient": 1e-8,
    "distributed-q": 2.5e-9,
}
SECONDS_PER_JOINT_ACTION = {"jal": 1e-8, "central-q": 2e-9}


def _cost(cell: CompareRun) -> float:
    """Estimated seconds of one run."""
    agents, actions = cell.size or (2, 3)
    joint_actions = actions**agents
    learner = cell.learner.name
    per_game = SECONDS_PER_GAME_ACTION.get(learner, 2e-8) * agents * actions
    if learner in JOINT_LEARNERS:
        per_game = SECONDS_PER_JOINT_ACTION.get(learner, 1e-8) * joint_actions * agents
    return 0.001 + per_game * cell.budget


COMPARE = Experiment(
    EXPERIMENT,
    CompareRun,
    run_compare,
    _warm_up,
    _cost,
    uses_device=lambda cell: isinstance(cell.learner, DeepLearnerConfig),
    keeps_policies=lambda cell: True,
)


def game_of_run(spec: Any) -> Any:
    """The repeated game a stored run of the comparison played (a random one remade from
    the run's game stream)."""
    cell = CompareRun.from_config(spec.config)
    make = GAMES[cell.game].make
    assert make is not None
    return make(cell.size, np.random.default_rng(spec.seed_sequence().spawn(3)[0]))


# ------------------------------------------------------------------------ summary


@dataclass(frozen=True)
class CompareCell:
    """The runs of one learner on one game (every size of a random family)."""

    learner: str
    game: str
    runs: int
    optimal_rate: float
    median_games: float | None
    """Median over runs of the games after which the greedy joint action never changed
    (None on the DSN)."""
    sizes: dict[str, dict[str, float]]
    """Random games: ``"n=…,m=…"`` -> runs and optimal rate of that size."""
    dsn: dict[str, float] | None = None
    """On the DSN: ``optimal_rate`` is the greedy policy's success rate (mean over runs),
    and this holds the DSN's other metrics (L, mean return and steps)."""
    label: str = ""
    """The learner's name in the tables, with the settings that differ from the
    comparison's (``CMARL-CD (delta=0.08)``): runs of two settings are two rows."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def summarize(records: Iterable[RunRecord]) -> list[CompareCell]:
    """One cell per (learner, game), in the registry's and :data:`GAMES`' order (the DSN
    last); ``records`` may hold the comparison's DSN runs too."""
    groups: dict[tuple[str, str, str], list[RunRecord]] = defaultdict(list)
    dsn_records = []
    for rec in records:
        if rec.key.experiment == EXPERIMENT:
            run = compare_run_of(rec)
            groups[(rec.key.algorithm, learner_label(run.learner), run.game)].append(rec)
        else:
            dsn_records.append(rec)
    learner_order = {name: i for i, name in enumerate(registry.REPEATED_LEARNERS)}
    game_order = {name: i for i, name in enumerate(GAMES)}
    cells = []
    for (learner, label, game), recs in sorted(
        groups.items(),
        key=lambda kv: (learner_order.get(kv[0][0], 99), kv[0][1], game_order[kv[0][2]]),
    ):
        cells.append(_cell(learner, label, game, recs))
    return cells + _dsn_cells(dsn_records)


def learner_label(learner: Any) -> str:
    """A learner's name with the settings that differ from the comparison's."""
    return registry.variant_label(learner, registry.comparable_learners().get(learner.name))


def _dsn_cells(records: Sequence[RunRecord]) -> list[CompareCell]:
    """The DSN column, one cell per learner, from the DSN rows at the comparison's L."""
    rows = episodic_results.summarize(DSN_GAME, records)
    return [
        CompareCell(
            learner=row.algorithm,
            game=DSN,
            runs=row.runs,
            optimal_rate=row.success_rate,
            median_games=None,
            sizes={},
            dsn={
                "episodes": row.episodes,
                "mean_return": row.mean_return,
                "mean_steps": row.mean_steps,
            },
            label=row.label,
        )
        for row in rows
    ]


def _cell(learner: str, label: str, game: str, records: Sequence[RunRecord]) -> CompareCell:
    by_size: dict[str, list[bool]] = defaultdict(list)
    for rec in records:
        size = compare_run_of(rec).size
        if size is not None:
            by_size[f"n={size[0]},m={size[1]}"].append(rec.metrics["optimal"])
    sizes = {
        size: {"runs": len(hits), "optimal_rate": sum(hits) / len(hits)}
        for size, hits in by_size.items()
    }
    return CompareCell(
        learner=learner,
        game=game,
        runs=len(records),
        optimal_rate=sum(bool(r.metrics["optimal"]) for r in records) / len(records),
        median_games=float(statistics.median(r.metrics["settled"] for r in records)),
        sizes=sizes,
        label=label,
    )
