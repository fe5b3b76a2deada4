"""The repeated-game experiment of Section IV-C (Tables 1 and 2).

Each run draws a fresh random cooperative game of the requested case, size and seed,
lets CMARL-CD (Algorithm 1) play it until every strategy is pure, and records whether
the greedy joint action is optimal and how many games it took.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any, Self

import numpy as np

from cmarlcd import paper
from cmarlcd.errors import require
from cmarlcd.games.matrix import MatrixGame, check_size, climbing_game, random_game
from cmarlcd.learners.tabular.coordination import CMARLCD, RepeatedConfig
from cmarlcd.limits import check_run_count, check_seed
from cmarlcd.paper import repeated_success
from cmarlcd.policies.keeping import POLICY, wanted
from cmarlcd.policies.learned import full_table
from cmarlcd.run_logs import log_point
from cmarlcd.runs import Experiment, RunRecord, RunSpec, Settings, identity, parse_settings
from cmarlcd.training.repeated import fit

EXPERIMENT = "repeated"
ALGORITHM = "cmarl-cd"
#: The paper's protocol: Table 1 (case 1) and Table 2 (case 2).
PAPER_AGENTS = paper.TABLE_AGENTS
PAPER_ACTIONS = paper.TABLE_ACTIONS
PAPER_RUNS = 50

_GRID_FIELDS = ("agents", "actions")


@dataclass(frozen=True)
class RepeatedCell(Settings):
    """One cell's runs: a fresh random game of ``case`` with ``agents`` agents of
    ``actions`` actions each, played by CMARL-CD with ``learner``'s settings (stored
    flat beside the cell's coordinates)."""

    case: int
    agents: int
    actions: int
    learner: RepeatedConfig = field(default_factory=RepeatedConfig)

    def to_config(self) -> dict[str, Any]:
        return {"case": self.case, "agents": self.agents, "actions": self.actions,
                **identity(self.learner)}  # fmt: skip

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> Self:
        return cls(config["case"], config["agents"], config["actions"], learner_config(config))


def cell_of(record: RunRecord) -> RepeatedCell:
    """The settings of a stored run."""
    return parse_settings(RepeatedCell, record.key.config)  # type: ignore[return-value]


@dataclass(frozen=True)
class RepeatedSweep:
    """A grid of (agents, actions) cells for one case, each played ``runs`` times."""

    case: int
    agents: tuple[int, ...]
    actions: tuple[int, ...]
    runs: int = PAPER_RUNS
    seed: int = 0
    learner: RepeatedConfig = field(default_factory=RepeatedConfig)

    def __post_init__(self) -> None:
        require(self.case in (1, 2), "case", f"must be 1 or 2 (got {self.case})")
        require(len(self.agents) > 0, "agents", "needs at least one value")
        require(len(self.actions) > 0, "actions", "needs at least one value")
        require(min(self.agents) >= 2, "agents", f"must be >= 2 (got {min(self.agents)})")
        require(min(self.actions) >= 2, "actions", f"must be >= 2 (got {min(self.actions)})")
        require(self.runs >= 1, "runs", f"must be >= 1 (got {self.runs})")
        check_seed(self.seed)
        check_size(max(self.agents), max(self.actions))
        check_run_count(self.run_count())

    def run_count(self) -> int:
        """Runs of the sweep, without listing them."""
        return len(self.agents) * len(self.actions) * self.runs

    def cells(self) -> list[RepeatedCell]:
        """One cell per (agents, actions)."""
        return [
            RepeatedCell(self.case, n, m, self.learner) for m in self.actions for n in self.agents
        ]

    def specs(self) -> list[RunSpec]:
        return [
            RunSpec.make(EXPERIMENT, ALGORITHM, cell, self.seed, r)
            for cell in self.cells()
            for r in range(self.runs)
        ]


def paper_sweep(case: int, runs: int = PAPER_RUNS, seed: int = 0) -> RepeatedSweep:
    """The full protocol of Table ``case``."""
    return RepeatedSweep(case, PAPER_AGENTS[case], PAPER_ACTIONS[case], runs, seed)


def learner_config(config: Mapping[str, Any]) -> RepeatedConfig:
    """The learner settings stored in a cell config."""
    names = {f.name for f in fields(RepeatedConfig)}
    return RepeatedConfig(**{k: v for k, v in config.items() if k in names})


def prepare_run(cell: RepeatedCell, seed: np.random.SeedSequence) -> tuple[MatrixGame, CMARLCD]:
    """A run's fresh random game and its untrained learners (independent streams)."""
    game_seed, learner_seed = seed.spawn(2)
    game = random_game(cell.case, cell.agents, cell.actions, np.random.default_rng(game_seed))
    return game, CMARLCD(game.action_counts, cell.learner, seed=learner_seed)


def run_cell(cell: RepeatedCell, seed: np.random.SeedSequence) -> dict[str, Any]:
    """One run: a fresh random game, CMARL-CD until pure, the paper's success test."""
    game, learner = prepare_run(cell, seed)
    result = fit(learner, game)
    metrics = {
        "success": result.success,
        "converged": result.converged,
        "games": result.games,
        "greedy_payoff": result.greedy_payoff,
        "max_reward_seen": learner.max_reward,
        "optima": len(game.optimal_joint_actions),
    }
    log_point(0, result.games, {"eval/greedy_payoff": result.greedy_payoff,
              "eval/success": float(result.success)}, "episodes")  # --log-dir  # fmt: skip
    if wanted():  # --save-policies: the greedy joint action, a table of the one state
        joint = np.array([result.greedy_joint_action], np.int64)
        meta = {"inputs": "state", "game": EXPERIMENT}
        metrics[POLICY] = full_table(joint, np.asarray(game.action_counts), meta)
    return metrics


def game_of_run(spec: RunSpec) -> MatrixGame:
    """The random game a stored run played, remade from its seeds."""
    return prepare_run(RepeatedCell.from_config(spec.config), spec.seed_sequence())[0]


def _warm_up() -> None:
    game = climbing_game()
    fit(CMARLCD(game.action_counts, seed=0), game, max_games=10)


def _cost(cell: RepeatedCell) -> float:
    """Estimated seconds of one run: case 1 needs about m^(n-1) games to meet an optimum,
    case 2 is quick (coefficients fitted to the paper protocol's stored wall times on a
    2-core machine, 2.3 µs per m^(n-1) and 0.16 ms per n·m)."""
    if cell.case == 1:
        return 2.3e-6 * float(cell.actions) ** (cell.agents - 1)
    return 1.6e-4 * cell.agents * cell.actions


REPEATED = Experiment(
    EXPERIMENT, RepeatedCell, run_cell, _warm_up, _cost, keeps_policies=lambda cell: True
)


@dataclass(frozen=True)
class CellSummary:
    """The runs of one (case, agents, actions) cell, aggregated as the paper reports them."""

    case: int
    agents: int
    actions: int
    runs: int
    success_rate: float
    converged_rate: float
    median_games: float | None
    """Median games to convergence over the converged runs (None if none converged)."""
    paper_success_rate: float | None
    """The paper's rate for this cell; None unless the learner's settings are the paper's."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def summarize(records: Iterable[RunRecord]) -> list[CellSummary]:
    """Aggregate stored runs per cell (runs of other settings must be filtered first)."""
    groups: dict[tuple[int, int, int], list[dict[str, Any]]] = defaultdict(list)
    paper_settings = True
    for rec in records:
        cell = cell_of(rec)
        groups[(cell.case, cell.agents, cell.actions)].append(rec.metrics)
        paper_settings &= cell.learner == RepeatedConfig()
    out = []
    for (case, n, m), metrics in sorted(groups.items(), key=lambda kv: (kv[0][2], kv[0][1])):
        games = [x["games"] for x in metrics if x["converged"]]
        out.append(
            CellSummary(
                case=case,
                agents=n,
                actions=m,
                runs=len(metrics),
                success_rate=sum(bool(x["success"]) for x in metrics) / len(metrics),
                converged_rate=sum(bool(x["converged"]) for x in metrics) / len(metrics),
                median_games=float(statistics.median(games)) if games else None,
                paper_success_rate=repeated_success(case, n, m) if paper_settings else None,
            )
        )
    return out


def group_key(cell: RepeatedCell, root_seed: int) -> tuple:
    """Runs that belong to one table: same settings apart from the cell coordinates."""
    rest = tuple(sorted((k, v) for k, v in cell.to_config().items() if k not in _GRID_FIELDS))
    return (root_seed, *rest)


def stored_tables(records: Iterable[RunRecord]) -> dict[tuple, list[RunRecord]]:
    """Group every stored repeated-game run into tables (one per case/settings/seed)."""
    tables: dict[tuple, list[RunRecord]] = defaultdict(list)
    for rec in records:
        tables[group_key(cell_of(rec), rec.key.root_seed)].append(rec)
    return dict(tables)


def settings_text(records: Sequence[RunRecord]) -> str:
    """What a table of runs shows: case, learner settings, seed, runs per cell."""
    cell = cell_of(records[0])
    learner, default = cell.learner, RepeatedConfig()
    counts = defaultdict(int)
    for rec in records:
        other = cell_of(rec)
        counts[(other.agents, other.actions)] += 1
    low, high = min(counts.values()), max(counts.values())
    runs = f"{low} runs per cell" if low == high else f"{low}-{high} runs per cell"
    extra = "".join(
        f", {name}={getattr(learner, name):g}"
        for name in ("purity_threshold", "max_games", "initial_degree")
        if getattr(learner, name) != getattr(default, name)
    )
    return (
        f"case {cell.case}, T={learner.temperature:g}, δ={learner.delta:g}{extra}, "
        f"seed {records[0].key.root_seed}, {runs}"
    )


def table_title(records: Sequence[RunRecord]) -> str:
    table = {1: "Table 1", 2: "Table 2"}[cell_of(records[0]).case]
    return f"{table} — success rate ({settings_text(records)})"
