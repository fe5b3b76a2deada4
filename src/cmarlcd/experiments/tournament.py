"""The blood battlefield tournament of Section V-B (Figs. 6-7).

A *round* has one match per pair of algorithms and one of each algorithm against itself
(10 matches for four). A match: both sides learn for ``learn_episodes`` episodes, then
play ``eval_episodes`` episodes with their fixed greedy strategies
(:class:`cmarlcd.training.match.Match`). Each match is one stored run (its round is the
run index), so a killed tournament resumes without recomputing a finished match.

[choice] Sides are balanced: in round ``r`` the first algorithm of a pair (in the order
they were given) plays side ``r % 2``; the sides are recorded with each match. Rounds of
a pairing with a deep learner may learn together (``seed_batch`` of the runner): their
deep sides then train as one stacked model, each match playing exactly what it plays
alone. In
self-play both sides are the same algorithm, and its rates are the mean of its two sides.

The choices the paper leaves open on the battlefield are one named setting each, a
:class:`Readings` (the discount and the max-return tolerance of the tabular learners,
what a tabular side plays in a state it never visited, the unit stats); its defaults are
the package's readings. A match records the readings that differ from the defaults and
apply to it (a match of two deep learners has no tabular side to change), so stores made
before these settings existed resume as they are, and matches no reading touches are
shared by the tournaments of several readings.

Per (algorithm, opponent) and round: the win, loss and tie rates of the algorithm's
side over the evaluation episodes, and its *win steps* (the mean turns of its won
episodes, undefined in a round it won none). Reported as mean and spread (population
standard deviation) over rounds.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.errors import check_discount, check_tolerance, require
from cmarlcd.games import battlefield
from cmarlcd.games.battlefield import GUNNER, MARINE, Battlefield, Unit
from cmarlcd.learners.automata import AutomatonConfig
from cmarlcd.learners.coordination import BATTLEFIELD_CMARLCD
from cmarlcd.learners.deep_config import BATTLEFIELD_DEEP, DeepConfig
from cmarlcd.learners.tabular import TabularConfig
from cmarlcd.limits import check_episodes, check_run_count, check_seed
from cmarlcd.registry import LearnerConfig
from cmarlcd.runs import Experiment, RunSpec
from cmarlcd.store import RunRecord
from cmarlcd.training.match import Match, MatchBatch
from cmarlcd.training.sides import UNSEEN_MODES, check_unseen

EXPERIMENT = "tournament"
PAPER_ROUNDS = 30
PAPER_LEARN_EPISODES = 500_000
PAPER_EVAL_EPISODES = 500_000
#: Rounds of a pairing with a deep learner that learn together (the runner's batch):
#: [choice] 10, see benchmarks/bench_battlefield.py for the measured gain.
SEED_BATCH = 10
#: [choice] Tables report the population standard deviation over rounds (ddof = 0).
STD_DDOF = 0


def battlefield_learners() -> dict[str, LearnerConfig]:
    """The paper's settings of each learner on the battlefield (Section V-B)."""
    return {
        "cmarl-cd": BATTLEFIELD_CMARLCD,
        "la-oca": AutomatonConfig(),
        "vdn": DeepConfig(mixer="vdn", **BATTLEFIELD_DEEP),
        "qmix": DeepConfig(mixer="qmix", **BATTLEFIELD_DEEP),
    }


#: The tabular learners (their loops are compiled once before workers fork).
TABULAR = ("cmarl-cd", "la-oca")


#: State indices a tabular side may address (its row index holds 8 bytes per index):
#: unit stats whose HP would make the battlefield larger are refused for CMARL-CD and
#: LA-OCA. The paper's battlefield has 802,816.
MAX_TABLE_STATES = 50_000_000
#: The unit kinds of a battlefield, in the order :class:`Readings` names them.
UNIT_KINDS = ("marine", "gunner")


def is_tabular(config: LearnerConfig) -> bool:
    """Whether a learner keeps tables (CMARL-CD, LA-OCA) rather than networks."""
    return isinstance(config, TabularConfig)


@dataclass(frozen=True)
class Readings:
    """How to read what Section V-B leaves open; the defaults are the package's readings.

    ``gamma`` and ``tolerance`` are the tabular learners' (the deep learners keep their
    own settings), None meaning each learner's own value.
    """

    gamma: float | None = None
    """[choice] Discount γ of eq. (1) for CMARL-CD and LA-OCA: None keeps theirs, 0.9 (as
    on the DSN); 0 reads the paper's "each player needs to consider only its own fire
    deployment" as each turn's own reward."""
    tolerance: float | None = None
    """[choice] Under which two returns count as equal in the max-return indicator
    (eq. 16) of CMARL-CD and LA-OCA: None keeps theirs, 1e-9 (equal up to rounding)."""
    unseen: str = UNSEEN_MODES[0]
    """[choice] What a tabular side plays at evaluation in a state it never visited:
    ``lowest`` (each agent's lowest legal target) or ``random`` (a uniformly random legal
    target, a draw of the learners' initial strategy)."""
    marine: Unit = MARINE
    """[choice] The marine's HP, damage and hit rate (Fig. 5 is not in the text)."""
    gunner: Unit = GUNNER
    """[choice] The gunner's HP, damage and hit rate."""

    def __post_init__(self) -> None:
        if self.gamma is not None:
            check_discount(self.gamma)
            object.__setattr__(self, "gamma", float(self.gamma))  # 0 and 0.0: one match
        if self.tolerance is not None:
            check_tolerance(self.tolerance)
            object.__setattr__(self, "tolerance", float(self.tolerance))
        check_unseen(self.unseen)

    def as_reading(self) -> dict[str, Any]:
        """These readings in the form :func:`reading_of` gives a stored match's."""
        return {
            "gamma": DEFAULT_READING["gamma"] if self.gamma is None else self.gamma,
            "tolerance": DEFAULT_READING["tolerance"] if self.tolerance is None else self.tolerance,
            "unseen": self.unseen,
            **{kind: unit_fields(getattr(self, kind)) for kind in UNIT_KINDS},
        }

    def rules(self) -> Battlefield:
        """The battlefield these unit stats make (the paper's troop of 4 + 2)."""
        return Battlefield(marine=self.marine, gunner=self.gunner)

    def apply(self, config: LearnerConfig) -> LearnerConfig:
        """``config`` with this reading's tabular settings (deep learners as they are)."""
        if not is_tabular(config):
            return config
        names = {f.name for f in fields(config)}
        changes = {
            k: v
            for k, v in (("gamma", self.gamma), ("tolerance", self.tolerance))
            if v is not None and k in names
        }
        return replace(config, **changes) if changes else config

    def stored(self, tabular: bool) -> dict[str, Any]:
        """What a pairing's stored config records of this reading: the parts that differ
        from the defaults and apply to it (``tabular``: it has a tabular side; the
        discount and tolerance travel in its learners' settings)."""
        out: dict[str, Any] = {}
        if (self.marine, self.gunner) != (MARINE, GUNNER):
            out["battlefield"] = {kind: unit_fields(getattr(self, kind)) for kind in UNIT_KINDS}
        if tabular and self.unseen != UNSEEN_MODES[0]:
            out["unseen"] = self.unseen
        return out


def unit_fields(unit: Unit) -> dict[str, Any]:
    """A unit as stored: ``{"hp": …, "damage": …, "hit_rate": …}``."""
    return asdict(unit)


def rules_of(config: Mapping[str, Any]) -> Battlefield:
    """The battlefield a stored pairing was played on (the paper's when not recorded)."""
    stats = config.get("battlefield")
    if stats is None:
        return battlefield.PAPER
    return Battlefield(**{kind: Unit(**stats[kind]) for kind in UNIT_KINDS})


def unseen_of(config: Mapping[str, Any]) -> str:
    """What a stored pairing's tabular sides played in unseen states."""
    return config.get("unseen", UNSEEN_MODES[0])


def pairings(names: Sequence[str]) -> list[tuple[str, str]]:
    """Every pair of ``names`` and each against itself, in the order given."""
    return [(names[i], names[j]) for i in range(len(names)) for j in range(i, len(names))]


@dataclass(frozen=True)
class Tournament:
    """Rounds of every pairing of ``learners`` on the battlefield; defaults are the
    paper's protocol."""

    learners: tuple[LearnerConfig, ...]
    rounds: int = PAPER_ROUNDS
    learn_episodes: int = PAPER_LEARN_EPISODES
    eval_episodes: int = PAPER_EVAL_EPISODES
    seed: int = 0
    readings: Readings = field(default_factory=Readings)
    """The readings of what the paper leaves open (:class:`Readings`)."""

    def __post_init__(self) -> None:
        names = [config.name for config in self.learners]
        require(len(names) > 0, "algorithms", "needs at least one algorithm")
        require(len(set(names)) == len(names), "algorithms", f"each at most once (got {names})")
        require(self.rounds >= 1, "rounds", f"must be >= 1 (got {self.rounds})")
        require(
            self.learn_episodes >= 1,
            "learn_episodes",
            f"must be >= 1 (got {self.learn_episodes})",
        )
        require(
            self.eval_episodes >= 1, "eval_episodes", f"must be >= 1 (got {self.eval_episodes})"
        )
        check_episodes(self.learn_episodes, "learn_episodes")
        check_episodes(self.eval_episodes, "eval_episodes")
        check_seed(self.seed)
        check_run_count(self.run_count(), "rounds")
        if any(is_tabular(config) for config in self.learners):
            states = self.readings.rules().n_states
            changed = [k for k in UNIT_KINDS if getattr(self.readings, k) != getattr(Readings(), k)]
            require(
                states <= MAX_TABLE_STATES,
                (changed or ["marine"])[0],
                f"these HP make {states:,} state indices per side; a tabular side (CMARL-CD, "
                f"LA-OCA) indexes at most {MAX_TABLE_STATES:,} (the paper's: 802,816)",
            )

    @property
    def playing(self) -> tuple[LearnerConfig, ...]:
        """The learners as they play: their settings with the readings applied."""
        return tuple(self.readings.apply(config) for config in self.learners)

    def run_count(self) -> int:
        """Matches of the tournament, without listing them."""
        n = len(self.learners)
        return n * (n + 1) // 2 * self.rounds

    @property
    def algorithms(self) -> tuple[str, ...]:
        return tuple(config.name for config in self.learners)

    def config(self, pair: tuple[LearnerConfig, LearnerConfig]) -> dict[str, Any]:
        """The stored config of one pairing's matches (``pair`` as they play)."""
        return {
            "algorithms": [config.name for config in pair],
            "learners": [asdict(config) for config in pair],
            "learn_episodes": self.learn_episodes,
            "eval_episodes": self.eval_episodes,
            **self.readings.stored(any(is_tabular(config) for config in pair)),
        }

    def specs(self) -> list[RunSpec]:
        """One spec per (pairing, round); a match's streams depend on its pairing, the
        learning budget, the unit stats and its round, not on the evaluation budget nor
        on what a side plays in unseen states (so ``unseen`` changes the evaluation
        alone: the sides learn exactly what they learn by default)."""
        by_name = {config.name: config for config in self.playing}
        specs = []
        for names in pairings(self.algorithms):
            config = self.config((by_name[names[0]], by_name[names[1]]))
            kept = ("algorithms", "learners", "learn_episodes", "battlefield")
            stream = {k: config[k] for k in kept if k in config}
            label = match_label(names)
            specs += [
                RunSpec.make(EXPERIMENT, label, config, self.seed, r, stream)
                for r in range(self.rounds)
            ]
        return specs


def match_label(names: Sequence[str]) -> str:
    """A pairing's name in the store: ``cmarl-cd vs la-oca``."""
    return " vs ".join(names)


# ------------------------------------------------------------------------- runs


def _learner(config: Mapping[str, Any], k: int) -> LearnerConfig:
    return registry.learner_config(config["algorithms"][k], config["learners"][k])


def play(config: dict[str, Any], seed: np.random.SeedSequence, round_index: int) -> dict[str, Any]:
    """One match: learn, evaluate, and the outcome from each side's view."""
    return play_rounds(config, [seed], [round_index])[0]


def play_rounds(
    config: dict[str, Any], seeds: Sequence[np.random.SeedSequence], rounds: Sequence[int]
) -> list[dict[str, Any]]:
    """The matches of one pairing in several rounds, learning together
    (:class:`cmarlcd.training.match.MatchBatch`: a deep learner's sides train as one
    stacked model); each plays and stores exactly what it would alone."""
    start = time.perf_counter()
    pair = (_learner(config, 0), _learner(config, 1))
    positions = [(0, 1) if r % 2 == 0 else (1, 0) for r in rounds]  # balanced sides
    streams = [[np.random.default_rng(s) for s in seed.spawn(4)] for seed in seeds]
    batch = MatchBatch(
        rules_of(config).spec(),
        pair,
        positions,
        [env for env, _, _, _ in streams],
        [(side0, side1) for _, side0, side1, _ in streams],
        config["learn_episodes"],
        unseen_of(config),
    )
    batch.learn()
    learn_seconds = (time.perf_counter() - start) / len(seeds)
    results = []
    for match, order, (_, _, _, eval_rng) in zip(batch.matches, positions, streams, strict=True):
        evaluated = time.perf_counter()
        result = match.evaluate(config["eval_episodes"], eval_rng)
        results.append(
            {
                "sides": [pair[p].name for p in order],
                "first_side": order.index(0),
                "episodes": result.episodes,
                "wins": list(result.wins),
                "ties": result.ties,
                "win_turns": list(result.win_turns),
                "turns": result.turns,
                "learn_turns": match.turns,
                "visited_states": [match.visited(0), match.visited(1)],
                "memory_megabytes": match.memory_bytes() / 1e6,
                "learn_seconds": learn_seconds,
                "seconds": learn_seconds + time.perf_counter() - evaluated,
            }
        )
    return results


def warm_up() -> None:
    """Compile the match loops of every playable pairing (once, before workers fork)."""
    configs = battlefield_learners()
    for a, b in pairings(TABULAR):
        rngs = [np.random.default_rng(k) for k in range(4)]
        pair = (configs[a], configs[b])
        match = Match(battlefield.SPEC, pair, rngs[0], (rngs[1], rngs[2]), 2)
        match.learn()
        match.evaluate(2, rngs[3])


def _work(config: Mapping[str, Any]) -> float:
    return float(config["learn_episodes"] + config["eval_episodes"])


def _cost(config: Mapping[str, Any]) -> float:
    """Estimated seconds of one match: about 14 µs per episode of two tabular sides, and
    a deep side adds about 8 times that (fitted to the quick preset's measured matches
    on the project's 2-core machine, benchmarks/fit_costs.py): matches with deep sides
    start first."""
    deep = sum(name not in TABULAR for name in config["algorithms"])
    return 14e-6 * _work(config) * (1 + 8 * deep)


def round_of(seed: np.random.SeedSequence) -> int:
    """A match's round: its run index, which :meth:`cmarlcd.runs.RunSpec.seed_sequence`
    puts last in the seed's spawn key."""
    return int(seed.spawn_key[-1])


def run(config: dict[str, Any], seed: np.random.SeedSequence) -> dict[str, Any]:
    """The runner's entry for one match."""
    return play(config, seed, round_of(seed))


def run_batch(config: dict[str, Any], seeds: list[np.random.SeedSequence]) -> list[dict[str, Any]]:
    """The runner's entry for the rounds of one pairing with a deep learner."""
    return play_rounds(config, seeds, [round_of(seed) for seed in seeds])


def has_deep_learner(config: Mapping[str, Any]) -> bool:
    """Whether a pairing has a deep learner (its rounds are worth batching)."""
    return any(name not in TABULAR for name in config["algorithms"])


TOURNAMENT = Experiment(
    EXPERIMENT,
    run=run,
    warm_up=warm_up,
    cost=_cost,
    run_batch=run_batch,
    batchable=has_deep_learner,
    work=_work,
    work_unit="episodes",
)


# ------------------------------------------------------------------- aggregation


def reading_of(config: Mapping[str, Any]) -> dict[str, Any]:
    """The readings a stored pairing was played under: the tabular learners' discount and
    tolerance and what they play in unseen states (None when it has no tabular side),
    and the unit stats."""
    tabular = [_learner(config, k) for k in range(2)]
    tabular = [learner for learner in tabular if is_tabular(learner)]
    rules = rules_of(config)

    def one(name: str) -> Any:
        values = sorted({getattr(learner, name) for learner in tabular})
        return None if not values else values[0] if len(values) == 1 else values

    return {
        "gamma": one("gamma"),
        "tolerance": one("tolerance"),
        "unseen": unseen_of(config) if tabular else None,
        **{kind: unit_fields(getattr(rules, kind)) for kind in UNIT_KINDS},
    }


#: The readings of a match played with the defaults (a tabular learner's γ and
#: tolerance: CMARL-CD's and LA-OCA's own).
DEFAULT_READING = {
    "gamma": BATTLEFIELD_CMARLCD.gamma,
    "tolerance": BATTLEFIELD_CMARLCD.tolerance,
    "unseen": UNSEEN_MODES[0],
    **{kind: unit_fields(unit) for kind, unit in zip(UNIT_KINDS, (MARINE, GUNNER), strict=True)},
}


def match_reading(records: Sequence[RunRecord]) -> dict[str, Any]:
    """The readings of one tournament's matches (:func:`tournaments`): a tabular
    learners' setting that differs among them is the list of its values; a tournament
    of deep learners alone has no tabular readings (None)."""
    readings = [reading_of(rec.config) for rec in records]
    tabular = [r for r in readings if r["unseen"] is not None]
    merged = dict(readings[0])
    for name in ("gamma", "tolerance", "unseen"):
        values = sorted({v for r in tabular for v in _as_list(r[name])})
        merged[name] = None if not values else values[0] if len(values) == 1 else values
    return merged


def _as_list(value: Any) -> list:
    return list(value) if isinstance(value, list) else [value]


def shared_hit_rate(reading: Mapping[str, Any]) -> float | None:
    """The hit rate every unit shares when the unit stats differ from the defaults in
    their hit rates alone (the readings study's dial), else None."""
    rates = {reading[kind]["hit_rate"] for kind in UNIT_KINDS}
    units = [{**reading[kind], "hit_rate": None} for kind in UNIT_KINDS]
    paper = [{**DEFAULT_READING[kind], "hit_rate": None} for kind in UNIT_KINDS]
    defaults = [DEFAULT_READING[kind] for kind in UNIT_KINDS]
    if len(rates) != 1 or units != paper or [reading[k] for k in UNIT_KINDS] == defaults:
        return None
    return rates.pop()


def reading_label(reading: Mapping[str, Any]) -> str:
    """What a reading changes from the defaults, in a few words (``defaults`` if
    nothing); parts a match has no side for (None) are left out."""
    words = []
    for name, symbol in (("gamma", "γ"), ("tolerance", "tolerance")):
        value = reading.get(name)
        if value is not None and value != DEFAULT_READING[name]:
            words.append(
                f"{symbol} = {value:g}" if not isinstance(value, list) else f"{symbol} = {value}"
            )
    if reading.get("unseen") not in (None, DEFAULT_READING["unseen"]):
        words.append(f"unseen states: {reading['unseen']}")
    rate = shared_hit_rate(reading)
    if rate is not None:
        return "; ".join([*words, f"hit rate {rate:g}"])
    for kind in UNIT_KINDS:
        unit, paper = reading[kind], DEFAULT_READING[kind]
        changed = [
            f"{k.replace('_', ' ')} {unit[k]:g}"
            for k in ("hp", "damage", "hit_rate")
            if unit[k] != paper[k]
        ]
        if changed:
            words.append(f"{kind} " + ", ".join(changed))
    return "; ".join(words) or "defaults"


def protocol_key(record: RunRecord) -> tuple:
    """What every match of one tournament shares: seed, budgets and unit stats (the
    tabular readings are told apart by :func:`tabular_key`)."""
    cfg = record.config
    rules = rules_of(cfg)
    units = tuple(tuple(unit_fields(getattr(rules, kind)).values()) for kind in UNIT_KINDS)
    return (record.key.root_seed, cfg["learn_episodes"], cfg["eval_episodes"], units)


def tabular_settings(config: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    """Each tabular learner's (γ, tolerance) in a stored pairing."""
    learners = [_learner(config, k) for k in range(2)]
    return {
        learner.name: (float(learner.gamma), float(learner.tolerance))
        for learner in learners
        if is_tabular(learner)
    }


def tabular_key(record: RunRecord) -> tuple | None:
    """The tabular readings of a match: what its tabular sides play in unseen states and
    the (γ, tolerance) they all share, or each one's when they differ (possible from the
    Python API only); None for a match of two deep learners."""
    settings = tabular_settings(record.config)
    if not settings:
        return None
    shared = set(settings.values())
    each = ("all", *shared.pop()) if len(shared) == 1 else ("each", *sorted(settings.items()))
    return (unseen_of(record.config), each)


def tournaments(records: Iterable[RunRecord]) -> list[list[RunRecord]]:
    """Stored matches grouped into tournaments: same seed, budgets and unit stats
    (:func:`protocol_key`), same tabular readings (:func:`tabular_key`). A match is in
    every tournament it was played for: a match of two deep learners in every one that
    has both of them (no tabular reading changes it), a tabular learner's match in one
    whose tabular learners have settings of their own when it has the same. A group
    that another one contains is not a tournament of its own."""
    buckets: dict[tuple, list[RunRecord]] = defaultdict(list)
    for rec in records:
        buckets[protocol_key(rec)].append(rec)
    return [group for bucket in buckets.values() for group in _tournaments_of(bucket)]


def _tournaments_of(records: Sequence[RunRecord]) -> list[list[RunRecord]]:
    """:func:`tournaments` among matches of one seed, budgets and unit stats."""
    by_key: dict[tuple, list[RunRecord]] = defaultdict(list)
    deep_only = []
    for rec in records:
        key = tabular_key(rec)
        if key is None:
            deep_only.append(rec)
        else:
            by_key[key].append(rec)
    groups = {key: list(recs) for key, recs in by_key.items()}
    for (unseen, shared), recs in by_key.items():
        if shared[0] != "each":
            continue
        own = dict(shared[1:])
        for (other_unseen, other), others in by_key.items():
            if other_unseen == unseen and other[0] == "all":
                recs += [
                    rec
                    for rec in others
                    if all(own.get(n) == other[1:] for n in tabular_settings(rec.config))
                ]
        groups[(unseen, shared)] = recs
    found = []
    for recs in groups.values():
        names = {name for rec in recs for name in rec.config["algorithms"]}
        found.append(recs + [r for r in deep_only if set(r.config["algorithms"]) <= names])
    if deep_only:
        found.append(deep_only)
    keys = [frozenset(rec.key for rec in group) for group in found]
    kept = [g for g, k in zip(found, keys, strict=True) if not any(k < other for other in keys)]
    return sorted(kept, key=lambda g: reading_label(match_reading(g)) != "defaults")


@dataclass(frozen=True)
class Cell:
    """One algorithm against one opponent, over rounds."""

    algorithm: str
    opponent: str
    rounds: int
    win_rate: float
    win_rate_std: float
    loss_rate: float
    loss_rate_std: float
    tie_rate: float
    tie_rate_std: float
    win_steps: float
    """Mean over rounds of the mean turns of the won episodes (NaN if it never won)."""
    win_steps_std: float

    def to_dict(self) -> dict[str, Any]:
        return {
            k: (None if isinstance(v, float) and math.isnan(v) else v)
            for k, v in asdict(self).items()
        }


def side_outcomes(metrics: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Each side's view of one match: who played it, against whom, and its rates."""
    n = metrics["episodes"]
    views = []
    for k in (0, 1):
        wins, losses = metrics["wins"][k], metrics["wins"][1 - k]
        turns = metrics["win_turns"][k]
        views.append(
            {
                "algorithm": metrics["sides"][k],
                "opponent": metrics["sides"][1 - k],
                "win_rate": wins / n,
                "loss_rate": losses / n,
                "tie_rate": metrics["ties"] / n,
                "win_steps": turns / wins if wins else math.nan,
            }
        )
    return views


#: The per-round quantities of a cell.
METRICS = ("win_rate", "loss_rate", "tie_rate", "win_steps")


def round_values(
    records: Iterable[RunRecord],
) -> dict[tuple[str, str], dict[int, dict[str, float]]]:
    """Per (algorithm, opponent) and round, each of :data:`METRICS` (a self-play round's
    value is the mean of its two sides)."""
    views: dict[tuple[str, str], dict[int, list[dict[str, Any]]]] = defaultdict(
        lambda: defaultdict(list)
    )
    for rec in records:
        for view in side_outcomes(rec.metrics):
            views[(view["algorithm"], view["opponent"])][rec.key.run_index].append(view)
    return {
        pair: {r: {m: _mean([v[m] for v in vs]) for m in METRICS} for r, vs in rounds.items()}
        for pair, rounds in views.items()
    }


def summarize(records: Iterable[RunRecord], order: Sequence[str] = ()) -> list[Cell]:
    """Cells (algorithm, opponent) from stored matches: rates per round, then mean and
    spread over rounds."""
    known = list(order) or list(registry.LEARNERS)
    rank = {name: i for i, name in enumerate(known)}
    cells = []
    for (algorithm, opponent), rounds in sorted(
        round_values(records).items(),
        key=lambda kv: (rank.get(kv[0][0], 99), rank.get(kv[0][1], 99)),
    ):
        spreads = [_mean_std([values[m] for values in rounds.values()]) for m in METRICS]
        cells.append(Cell(algorithm, opponent, len(rounds), *(x for pair in spreads for x in pair)))
    return cells


def _mean(values: Sequence[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


def _mean_std(values: Sequence[float]) -> tuple[float, float]:
    finite = np.array([v for v in values if not math.isnan(v)])
    if finite.size == 0:
        return math.nan, math.nan
    return float(finite.mean()), float(finite.std(ddof=STD_DDOF))


def round_rates(
    records: Iterable[RunRecord], algorithm: str, opponent: str, metric: str = "win_rate"
) -> dict[int, float]:
    """``metric`` of ``algorithm`` against ``opponent`` in each round."""
    rounds = round_values(records).get((algorithm, opponent), {})
    return {r: values[metric] for r, values in rounds.items()}


# ------------------------------------------------------------------- the claims

#: The verdicts of a claim: it holds beyond the noise, the opposite holds beyond the
#: noise, the rounds cannot tell, or the tournament lacks an algorithm it needs.
SUPPORTED, CONTRADICTED, NOT_SEPARATED, NOT_CHECKED = (
    "supported",
    "contradicted",
    "not separated",
    "not checked",
)
#: [choice] A claim's margin counts when it is more than this many standard errors (over
#: rounds) from 0.
STANDARD_ERRORS = 2.0
#: The paper's threshold for "wins under 40 % against CMARL-CD".
UNDER = 0.4


@dataclass(frozen=True)
class Margin:
    """One comparison behind a claim: the margin by which it holds (> 0: as the paper
    says), against whom, its standard error over rounds, and the rounds it rests on."""

    against: str
    value: float
    standard_error: float
    rounds: int

    @property
    def verdict(self) -> str:
        """SUPPORTED, CONTRADICTED or NOT_SEPARATED (:data:`STANDARD_ERRORS`)."""
        if self.rounds == 0:
            return NOT_SEPARATED
        if self.value > STANDARD_ERRORS * self.standard_error:
            return SUPPORTED
        if self.value < -STANDARD_ERRORS * self.standard_error:
            return CONTRADICTED
        return NOT_SEPARATED


@dataclass(frozen=True)
class Claim:
    """One claim of the paper (Section V-B) against our matches."""

    claim: str
    verdict: str
    """SUPPORTED, CONTRADICTED, NOT_SEPARATED or NOT_CHECKED."""
    evidence: str
    margins: tuple[Margin, ...] = ()
    """The comparisons it rests on (all must hold for SUPPORTED, one against it makes
    it CONTRADICTED)."""

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for margin in out["margins"]:
            for key in ("value", "standard_error"):
                if not math.isfinite(margin[key]):
                    margin[key] = None
        return out


#: The claims of Section V-B, in the order the paper makes them.
CLAIMS = (
    "CMARL-CD has the higher win rate against every other algorithm",
    "QMIX beats LA-OCA",
    "VDN beats LA-OCA",
    "QMIX wins under 40 % against CMARL-CD",
    "VDN wins under 40 % against CMARL-CD",
    "CMARL-CD needs the fewest win steps",
)


def _standard_error(values: np.ndarray) -> float:
    """The standard error of the mean of per-round values (infinite from one round)."""
    return float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else math.inf


def _margin(against: str, values: Sequence[float]) -> Margin:
    finite = np.array([v for v in values if not math.isnan(v)])
    if finite.size == 0:
        return Margin(against, math.nan, math.nan, 0)
    return Margin(against, float(finite.mean()), _standard_error(finite), int(finite.size))


def _paired(records: Sequence[RunRecord], a: str, b: str) -> Margin:
    """Per round, (win rate of a against b) - (win rate of b against a)."""
    mine, theirs = round_rates(records, a, b), round_rates(records, b, a)
    rounds = sorted(set(mine) & set(theirs))
    return _margin(b, [mine[r] - theirs[r] for r in rounds])


def _below(records: Sequence[RunRecord], a: str, b: str, threshold: float) -> Margin:
    """Per round, ``threshold`` minus the win rate of a against b."""
    return _margin(b, [threshold - rate for rate in round_rates(records, a, b).values()])


def _plus_minus(margin: Margin, scale: float = 100.0, unit: str = "") -> str:
    spread = STANDARD_ERRORS * margin.standard_error * scale
    return f"{margin.value * scale:+.1f}{unit} ± {spread:.1f}{unit}, {margin.rounds} rounds"


def _combined(text: str, margins: Sequence[Margin], evidence: str) -> Claim:
    verdicts = [m.verdict for m in margins]
    if all(v == SUPPORTED for v in verdicts):
        verdict = SUPPORTED
    elif any(v == CONTRADICTED for v in verdicts):
        verdict = CONTRADICTED
    else:
        verdict = NOT_SEPARATED
    return Claim(text, verdict, evidence, tuple(margins))


def check_claims(records: Sequence[RunRecord], cells: Sequence[Cell]) -> list[Claim]:
    """Each claim of :data:`CLAIMS`, with our numbers: a margin per comparison, counted
    when it is more than :data:`STANDARD_ERRORS` standard errors over rounds from 0."""
    table = {(c.algorithm, c.opponent): c for c in cells}
    names = {c.algorithm for c in cells}

    def missing(*required: str) -> Claim | None:
        lacking = [registry.display_name(n) for n in required if n not in names]
        return ", ".join(lacking) if lacking else None

    def unplayed(text: str, a: str, others: Sequence[str]) -> Claim | None:
        lacking = [o for o in others if (a, o) not in table or (o, a) not in table]
        if not lacking:
            return None
        pairs = ", ".join(
            f"{registry.display_name(a)} vs {registry.display_name(o)}" for o in lacking
        )
        return Claim(text, NOT_CHECKED, f"no match of {pairs}")

    def beats(text: str, a: str, others: Sequence[str]) -> Claim:
        if (why := unplayed(text, a, others)) is not None:
            return why
        margins = [_paired(records, a, o) for o in others]
        evidence = "; ".join(
            f"{registry.display_name(a)} wins {table[(a, m.against)].win_rate:.1%} against "
            f"{registry.display_name(m.against)}, which wins "
            f"{table[(m.against, a)].win_rate:.1%} (difference {_plus_minus(m, unit=' %')})"
            for m in margins
        )
        return _combined(text, margins, evidence)

    claims = []
    others = sorted(names - {"cmarl-cd"}, key=_rank)
    first = CLAIMS[0]
    if (lacking := missing("cmarl-cd")) or not others:
        why = f"needs {lacking} in the tournament" if lacking else "needs a second algorithm"
        claims.append(Claim(first, NOT_CHECKED, why))
    else:
        claims.append(beats(first, "cmarl-cd", others))
    for deep, text in (("qmix", CLAIMS[1]), ("vdn", CLAIMS[2])):
        if lacking := missing(deep, "la-oca"):
            claims.append(Claim(text, NOT_CHECKED, f"needs {lacking} in the tournament"))
        else:
            claims.append(beats(text, deep, ["la-oca"]))
    for deep, text in (("qmix", CLAIMS[3]), ("vdn", CLAIMS[4])):
        if lacking := missing(deep, "cmarl-cd"):
            claims.append(Claim(text, NOT_CHECKED, f"needs {lacking} in the tournament"))
            continue
        if (why := unplayed(text, deep, ["cmarl-cd"])) is not None:
            claims.append(why)
            continue
        margin = _below(records, deep, "cmarl-cd", UNDER)
        cell = table[(deep, "cmarl-cd")]
        evidence = (
            f"{cell.win_rate:.1%} ± {cell.win_rate_std:.1%} (spread); 40 % minus it: "
            f"{_plus_minus(margin, unit=' %')}"
        )
        claims.append(_combined(text, [margin], evidence))
    claims.append(_fewest_win_steps(records, names))
    return claims


def _fewest_win_steps(records: Sequence[RunRecord], names: set[str]) -> Claim:
    """CMARL-CD against each other algorithm X: per round, X's mean win steps over its
    opponents minus CMARL-CD's; the claim holds against X when that difference is more
    than two standard errors above 0."""
    text = CLAIMS[5]
    if "cmarl-cd" not in names or len(names) < 2:
        return Claim(text, NOT_CHECKED, "needs CMARL-CD and another algorithm")
    margins = [
        _margin(other, _win_step_differences(records, other, "cmarl-cd", sorted(names)))
        for other in sorted(names - {"cmarl-cd"}, key=_rank)
    ]
    evidence = "; ".join(
        f"{registry.display_name(m.against)}: no rounds won by both"
        if m.rounds == 0
        else f"{registry.display_name(m.against)} needs {m.value:+.2f} ± "
        f"{STANDARD_ERRORS * m.standard_error:.2f} turns more ({m.rounds} rounds)"
        for m in margins
    )
    return _combined(text, margins, evidence)


def _win_step_differences(
    records: Sequence[RunRecord], other: str, ours: str, opponents: Sequence[str]
) -> list[float]:
    """Per round: the mean win steps of ``other`` over its opponents minus those of
    ``ours`` (rounds where either won nothing are left out)."""

    def per_round(name: str) -> dict[int, float]:
        by_round: dict[int, list[float]] = defaultdict(list)
        for opponent in opponents:
            for r, steps in round_rates(records, name, opponent, "win_steps").items():
                by_round[r].append(steps)
        return {r: _mean(values) for r, values in by_round.items()}

    theirs, mine = per_round(other), per_round(ours)
    rounds = sorted(set(theirs) & set(mine))
    return [d for d in (theirs[r] - mine[r] for r in rounds) if not math.isnan(d)]


def _rank(name: str) -> int:
    known = list(registry.LEARNERS)
    return known.index(name) if name in known else len(known)
