"""The distributed sensor network protocol of Section V-A (Tables 3-7, Fig. 4).

Each run trains a learner on the DSN and evaluates its fixed greedy joint policy for
``eval_episodes`` episodes after each budget ``L`` of learning episodes. The tabular
learners' schedules do not depend on ``L``, so one run trains once to the largest ``L``
and is evaluated at every checkpoint on the way; evaluation draws from its own stream
(keyed by ``L``), so a checkpoint's numbers do not depend on which others were asked for.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from cmarlcd.errors import require
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep_config import DeepConfig
from cmarlcd.learners.stochastic import AutomatonConfig, RuleParams, StochasticConfig
from cmarlcd.paper import DSN_ALGORITHMS, DSN_EPISODES, dsn_value
from cmarlcd.rollouts import dsn_evaluate, dsn_tables, greedy_policy, train_dsn
from cmarlcd.runner import Experiment, RunSpec, register, report_progress
from cmarlcd.store import RunRecord

EXPERIMENT = "dsn"
#: Learners available to this protocol: display name and the paper's settings.
ALGORITHMS: dict[str, tuple[str, StochasticConfig | AutomatonConfig | DeepConfig]] = {
    "cmarl-cd": ("CMARL-CD", StochasticConfig()),
    "la-oca": ("LA-OCA", AutomatonConfig()),
    "vdn": ("VDN", DeepConfig(mixer="vdn")),
    "qmix": ("QMIX", DeepConfig(mixer="qmix")),
}
#: The deep baselines: their ε schedule depends on L, so each L is a separate run.
DEEP = ("vdn", "qmix")
#: Seeds of one deep config trained together in one stacked model (the runner's batch).
#: [choice] 10: on the 2-core CPU benchmark B = 10 gives the best aggregate env steps/s for
#: VDN (2.8x B = 1) and is within 10 % of B = 50 for QMIX (1.9x against 2.1x), with a fifth
#: of the memory and finer work units for the workers (see benchmarks/bench_deep.py).
SEED_BATCH = 10
PAPER_RUNS = 50
PAPER_EVAL_EPISODES = 50_000
#: [choice] Learning-curve resolution: greedy evaluations at this many evenly spaced
#: points up to the largest L, each over CURVE_EVAL_EPISODES episodes.
CURVE_POINTS = 20
CURVE_EVAL_EPISODES = 2_000
#: [choice] Tables 4-5 report the population standard deviation over runs (ddof = 0).
STD_DDOF = 0
#: The per-(algorithm, L) quantities of Tables 3-7, in the order of the JSON output.
TABLE_METRICS = (
    "success_rate",
    "mean_return",
    "std_return",
    "mean_steps",
    "std_steps",
    "min_return",
    "max_steps",
)


@dataclass(frozen=True)
class DsnSweep:
    """Algorithms × runs on the DSN, each evaluated after every budget in ``episodes``."""

    algorithms: tuple[str, ...] = ("cmarl-cd", "la-oca")
    episodes: tuple[int, ...] = DSN_EPISODES
    runs: int = PAPER_RUNS
    eval_episodes: int = PAPER_EVAL_EPISODES
    seed: int = 0
    cmarlcd: StochasticConfig = field(default_factory=StochasticConfig)
    laoca: AutomatonConfig = field(default_factory=AutomatonConfig)
    vdn: DeepConfig = ALGORITHMS["vdn"][1]
    qmix: DeepConfig = ALGORITHMS["qmix"][1]
    curve_points: int = CURVE_POINTS
    curve_eval_episodes: int = CURVE_EVAL_EPISODES

    def __post_init__(self) -> None:
        require(len(self.algorithms) > 0, "algorithms", "needs at least one algorithm")
        for name in self.algorithms:
            known = ", ".join(ALGORITHMS)
            require(name in ALGORITHMS, "algorithms", f"unknown {name!r}; available: {known}")
        require(len(self.episodes) > 0, "episodes", "needs at least one budget")
        require(min(self.episodes) >= 1, "episodes", f"must be >= 1 (got {min(self.episodes)})")
        require(self.runs >= 1, "runs", f"must be >= 1 (got {self.runs})")
        require(
            self.eval_episodes >= 1, "eval_episodes", f"must be >= 1 (got {self.eval_episodes})"
        )
        require(self.seed >= 0, "seed", f"must be >= 0 (got {self.seed})")
        require(self.curve_points >= 0, "curve_points", f"must be >= 0 (got {self.curve_points})")
        require(
            self.curve_eval_episodes >= 1,
            "curve_eval_episodes",
            f"must be >= 1 (got {self.curve_eval_episodes})",
        )

    def learner_config(self, algorithm: str) -> StochasticConfig | AutomatonConfig | DeepConfig:
        return getattr(self, algorithm.replace("-", ""))

    def config(self, algorithm: str, budgets: Sequence[int] | None = None) -> dict[str, Any]:
        """The stored config of one algorithm's runs (evaluated after each budget)."""
        return {
            "algorithm": algorithm,
            "checkpoints": sorted(set(budgets or self.episodes)),
            "eval_episodes": self.eval_episodes,
            "curve_points": self.curve_points,
            "curve_eval_episodes": self.curve_eval_episodes,
            "learner": asdict(self.learner_config(algorithm)),
        }

    def specs(self) -> list[RunSpec]:
        """Tabular learners: one spec per (algorithm, run), trained once to the largest L,
        with streams that depend on the learner only. Deep learners: one spec per
        (algorithm, L, run), streams depending on the learner and L."""
        specs = []
        for name in self.algorithms:
            groups = [[b] for b in sorted(set(self.episodes))] if name in DEEP else [None]
            for budgets in groups:
                config = self.config(name, budgets)
                stream = {"algorithm": name, "learner": config["learner"]}
                if budgets:
                    stream["episodes"] = budgets[0]
                specs += [
                    RunSpec.make(EXPERIMENT, name, config, self.seed, r, stream)
                    for r in range(self.runs)
                ]
        return specs


def learner(config: Mapping[str, Any]) -> StochasticConfig | AutomatonConfig | DeepConfig:
    """The learner settings of a stored config."""
    return type(ALGORITHMS[config["algorithm"]][1])(**config["learner"])


def rule_params(config: Mapping[str, Any]) -> RuleParams:
    """The compiled rule parameters of a stored (tabular) config."""
    return learner(config).rule_params()


def _keyed_rng(seed: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """A stream that depends only on ``seed`` and ``key`` (e.g. an evaluation at L)."""
    child = np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, *key))
    return np.random.default_rng(child)


def _evaluate(policy: np.ndarray, episodes: int, rng: np.random.Generator) -> dict[str, float]:
    successes, total_return, total_steps = dsn_evaluate(policy, episodes, rng)
    return {
        "success_rate": successes / episodes,
        "mean_return": total_return / episodes,
        "mean_steps": total_steps / episodes,
    }


def _schedule(config: Mapping[str, Any]) -> list[int]:
    """Every budget at which the run stops to evaluate: checkpoints and curve points."""
    largest = max(config["checkpoints"])
    points = config["curve_points"]
    curve = {round(largest * k / points) for k in range(1, points + 1)} if points else set()
    return sorted(curve | set(config["checkpoints"]) - {0})


class _Recorder:
    """Evaluates a run's greedy policy at each budget: the checkpoints of Tables 3-7 with
    ``eval_episodes`` episodes, every budget with ``curve_eval_episodes`` for the curve."""

    def __init__(self, config: Mapping[str, Any], eval_seed: np.random.SeedSequence) -> None:
        self.config, self.eval_seed = config, eval_seed
        self.checkpoints: dict[str, dict[str, float]] = {}
        self.curve: list[list[float]] = []
        self.policy = np.zeros((dsn.N_STATE_INDICES, dsn.N_SENSORS), dtype=np.int64)
        self.start = time.perf_counter()

    def __call__(self, budget: int, policy: np.ndarray) -> None:
        cfg = self.config
        if budget in cfg["checkpoints"]:
            rng = _keyed_rng(self.eval_seed, 0, budget)
            self.checkpoints[str(budget)] = _evaluate(policy, cfg["eval_episodes"], rng)
        point = _evaluate(policy, cfg["curve_eval_episodes"], _keyed_rng(self.eval_seed, 1, budget))
        self.curve.append(
            [budget, point["success_rate"], point["mean_return"], point["mean_steps"]]
        )
        self.policy = policy

    def metrics(self) -> dict[str, Any]:
        return {
            "checkpoints": self.checkpoints,
            "curve": self.curve,
            "policy": self.policy[: dsn.N_STATES].tolist(),
            "seconds": time.perf_counter() - self.start,
        }


def run_dsn(config: dict[str, Any], seed: np.random.SeedSequence) -> dict[str, Any]:
    """One run: train to each budget in turn, evaluating the greedy policy at each."""
    if config["algorithm"] in DEEP:
        return run_dsn_batch(config, [seed])[0]
    env_seed, agent_seed, eval_seed = seed.spawn(3)
    env_rng, agent_rng = np.random.default_rng(env_seed), np.random.default_rng(agent_seed)
    tables = dsn_tables(rule_params(config))
    record, trained = _Recorder(config, eval_seed), 0
    for budget in _schedule(config):
        report_progress(train_dsn(tables, budget - trained, env_rng, agent_rng))
        trained = budget
        record(budget, greedy_policy(tables))
    return record.metrics()


def run_dsn_batch(
    config: dict[str, Any], seeds: list[np.random.SeedSequence]
) -> list[dict[str, Any]]:
    """VDN / QMIX runs of one config, all seeds trained together in one stacked model."""
    from cmarlcd.deep_training import DsnDeepBatch  # needs the [deep] extra

    train_seeds, eval_seeds = zip(*(s.spawn(2) for s in seeds), strict=True)
    records = [_Recorder(config, e) for e in eval_seeds]
    batch = DsnDeepBatch(learner(config), train_seeds, max(config["checkpoints"]))
    batch.train(_schedule(config), lambda k, budget, table: records[k](budget, table))
    return [r.metrics() for r in records]


def _warm_up() -> None:
    tables = dsn_tables(StochasticConfig().rule_params())
    train_dsn(tables, 2, np.random.default_rng(0), np.random.default_rng(1))
    dsn_evaluate(greedy_policy(tables), 2, np.random.default_rng(2))
    tables = dsn_tables(AutomatonConfig().rule_params())
    train_dsn(tables, 2, np.random.default_rng(0), np.random.default_rng(1))


def _cost(config: Mapping[str, Any]) -> float:
    scale = 100.0 if config["algorithm"] in DEEP else 1.0
    return scale * max(config["checkpoints"]) + config["eval_episodes"]


def _batch_limit(config: Mapping[str, Any]) -> int:
    return SEED_BATCH if config["algorithm"] in DEEP else 1


DSN = register(
    Experiment(
        EXPERIMENT, run_dsn, _warm_up, _cost, run_batch=run_dsn_batch, batch_limit=_batch_limit
    )
)


# ------------------------------------------------------------------- aggregation


@dataclass(frozen=True)
class DsnRow:
    """One (algorithm, L) entry of Tables 3-7, aggregated over runs."""

    algorithm: str
    label: str
    """Display name; marked * when the learner's settings differ from the paper's."""
    episodes: int
    runs: int
    success_rate: float
    mean_return: float
    std_return: float
    mean_steps: float
    std_steps: float
    min_return: float
    max_steps: float
    paper: dict[str, float | None]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def row_label(algorithm: str, learner: Mapping[str, Any]) -> str:
    """The algorithm's name, marked with * when its settings are not the paper's."""
    _, paper = ALGORITHMS.get(algorithm, (None, None))
    default = paper is not None and asdict(paper) == dict(learner)
    return display_name(algorithm) + ("" if default else " *")


def summarize(records: Iterable[RunRecord]) -> list[DsnRow]:
    """Tables 3-7 from stored runs: one row per (algorithm, settings, L), paper values attached."""
    per_cell: dict[tuple[str, str, int], dict[int, dict[str, float]]] = defaultdict(dict)
    for rec in records:
        label = row_label(rec.key.algorithm, rec.config["learner"])
        for budget, result in rec.metrics["checkpoints"].items():
            # keyed by run: sweeps with other checkpoint lists hold the very same run at L
            per_cell[(rec.key.algorithm, label, int(budget))][rec.key.run_index] = result
    rows = []
    for (name, label, budget), by_run in sorted(per_cell.items(), key=_row_order):
        results = list(by_run.values())
        success = np.array([r["success_rate"] for r in results])
        returns = np.array([r["mean_return"] for r in results])
        steps = np.array([r["mean_steps"] for r in results])
        rows.append(
            DsnRow(
                algorithm=name,
                label=label,
                episodes=budget,
                runs=len(results),
                success_rate=float(success.mean()),
                mean_return=float(returns.mean()),
                std_return=float(returns.std(ddof=STD_DDOF)),
                mean_steps=float(steps.mean()),
                std_steps=float(steps.std(ddof=STD_DDOF)),
                min_return=float(returns.min()),
                max_steps=float(steps.max()),
                paper={m: dsn_value(name, budget, m) for m in TABLE_METRICS},
            )
        )
    return rows


def _row_order(item: tuple[tuple[str, str, int], Any]) -> tuple[int, str, int]:
    (name, label, budget), _ = item
    known = DSN_ALGORITHMS
    return (known.index(name) if name in known else len(known), label, budget)


def learning_curves(records: Iterable[RunRecord]) -> dict[str, np.ndarray]:
    """Per row label, an array (runs, points, 4) of [episodes, success, return, steps]."""
    curves: dict[str, list[list[list[float]]]] = defaultdict(list)
    for rec in records:
        label = row_label(rec.key.algorithm, rec.config["learner"])
        if rec.key.algorithm in DEEP:
            label += f", L = {max(rec.config['checkpoints']):,}"
        curves[label].append(rec.metrics["curve"])
    return {label: np.array(runs) for label, runs in curves.items() if runs and runs[0]}


def protocol_key(record: RunRecord) -> tuple:
    """Runs that belong in one set of Tables 3-7: same seed, budgets and evaluation."""
    cfg = record.config
    fields = ("eval_episodes", "curve_points", "curve_eval_episodes")
    return (record.key.root_seed, *(str(cfg[f]) for f in fields))


def display_name(algorithm: str) -> str:
    return ALGORITHMS.get(algorithm, (algorithm.upper(), None))[0]
