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
alone.

The choices the paper leaves open on the battlefield are one named setting each, a
:class:`Readings` (the discount and the max-return tolerance of the tabular learners,
what a tabular side plays in a state it never visited, the unit stats); its defaults are
the package's readings. A match records the readings that differ from the defaults and
apply to it (a match of two deep learners has no tabular side to change), so stores made
before these settings existed resume as they are, and matches no reading touches are
shared by the tournaments of several readings.

This module plans and plays the matches; :mod:`~.tournament_results` reads stored
matches back into tournaments and Figs. 6-7, :mod:`~.tournament_claims` checks the
paper's claims on them.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Self

import numpy as np

from cmarlcd import registry
from cmarlcd.errors import check_discount, check_tolerance, require
from cmarlcd.experiments.match_policies import match_policies
from cmarlcd.games import battlefield
from cmarlcd.games.battlefield import GUNNER, MARINE, Battlefield, Unit
from cmarlcd.learners.tabular.coordination import BATTLEFIELD_CMARLCD
from cmarlcd.limits import check_episodes, check_run_count, check_seed
from cmarlcd.policies.keeping import POLICY, wanted
from cmarlcd.registry import LearnerConfig
from cmarlcd.run_logs import log_point
from cmarlcd.runs import Experiment, RunRecord, RunSpec, Settings, identity, parse_settings
from cmarlcd.training.match import Match, MatchBatch
from cmarlcd.training.tabular_side import UNSEEN_MODES, check_unseen

EXPERIMENT = "tournament"
PAPER_ROUNDS = 30
PAPER_LEARN_EPISODES = 500_000
PAPER_EVAL_EPISODES = 500_000
#: Rounds of a pairing with a deep learner that learn together (the runner's batch):
#: [choice] 10, see benchmarks/bench_battlefield.py for the measured gain.
SEED_BATCH = 10
#: [choice] Tables report the population standard deviation over rounds (ddof = 0).
STD_DDOF = 0


def is_tabular(config: LearnerConfig) -> bool:
    """Whether a learner keeps tables (CMARL-CD, LA-OCA) rather than networks."""
    return registry.kind_of(config) == registry.TABULAR


def battlefield_learners() -> dict[str, LearnerConfig]:
    """Each learner's settings on the battlefield (the paper's, Section V-B, for its
    four), from the registry's battlefield presets."""
    return registry.learners_on(registry.BATTLEFIELD)


def paper_learners() -> dict[str, LearnerConfig]:
    """The four learners of the paper's tournament, with its settings."""
    every = battlefield_learners()
    return {name: every[name] for name in registry.PAPER_LEARNERS}


#: The tabular learners of the battlefield (their loops are compiled once before workers
#: fork), found by their kind, not by name.
TABULAR = tuple(name for name, config in battlefield_learners().items() if is_tabular(config))


#: State indices a tabular side may address (its row index holds 8 bytes per index):
#: unit stats whose HP would make the battlefield larger are refused for CMARL-CD and
#: LA-OCA. The paper's battlefield has 802,816.
MAX_TABLE_STATES = 50_000_000
#: The unit kinds of a battlefield, in the order :class:`Readings` names them.
UNIT_KINDS = ("marine", "gunner")


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
            # 0, 0.0 and -0.0: one match
            object.__setattr__(self, "gamma", float(self.gamma) + 0.0)
        if self.tolerance is not None:
            check_tolerance(self.tolerance)
            object.__setattr__(self, "tolerance", float(self.tolerance) + 0.0)
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


@dataclass(frozen=True)
class Pairing(Settings):
    """The matches of one pairing: two learners as they play (readings applied), the
    learning and evaluation budgets, the unit stats, and what a tabular side plays in
    unseen states.

    The stored config records the unit stats and ``unseen`` only where they differ from
    the defaults and apply (``unseen``: a tabular side plays); the discount and tolerance
    travel in the learners' settings.
    """

    learners: tuple[LearnerConfig, LearnerConfig]
    learn_episodes: int
    eval_episodes: int
    marine: Unit = MARINE
    gunner: Unit = GUNNER
    unseen: str = UNSEEN_MODES[0]

    @property
    def algorithms(self) -> tuple[str, str]:
        return (self.learners[0].name, self.learners[1].name)

    @property
    def rules(self) -> Battlefield:
        """The battlefield its matches are played on (the paper's troop of 4 + 2)."""
        if (self.marine, self.gunner) == (MARINE, GUNNER):
            return battlefield.PAPER
        return Battlefield(marine=self.marine, gunner=self.gunner)

    @property
    def has_tabular(self) -> bool:
        return any(is_tabular(learner) for learner in self.learners)

    @property
    def has_deep(self) -> bool:
        """Whether a side is a deep learner (its rounds are worth batching)."""
        return any(registry.needs_torch(name) for name in self.algorithms)

    def to_config(self) -> dict[str, Any]:
        config: dict[str, Any] = {
            "algorithms": list(self.algorithms),
            "learners": [identity(learner) for learner in self.learners],
            "learn_episodes": self.learn_episodes,
            "eval_episodes": self.eval_episodes,
        }
        if (self.marine, self.gunner) != (MARINE, GUNNER):
            units = (self.marine, self.gunner)
            config["battlefield"] = {
                k: unit_fields(u) for k, u in zip(UNIT_KINDS, units, strict=True)
            }
        if self.has_tabular and self.unseen != UNSEEN_MODES[0]:
            config["unseen"] = self.unseen
        return config

    @classmethod
    def from_config(cls, config: Mapping[str, Any]) -> Self:
        learners = tuple(
            registry.learner_config(name, settings)
            for name, settings in zip(config["algorithms"], config["learners"], strict=True)
        )
        stats = config.get("battlefield") or {kind: None for kind in UNIT_KINDS}
        units = [Unit(**u) if u else default for u, default in zip(
            (stats["marine"], stats["gunner"]), (MARINE, GUNNER), strict=True)]  # fmt: skip
        return cls(
            learners,  # type: ignore[arg-type]
            config["learn_episodes"],
            config["eval_episodes"],
            *units,
            config.get("unseen", UNSEEN_MODES[0]),
        )

    def stream(self) -> dict[str, Any]:
        """What seeds a match: not the evaluation budget, nor what a side plays in
        unseen states (``unseen`` changes the evaluation alone: the sides learn exactly
        what they learn by default)."""
        config = self.to_config()
        kept = ("algorithms", "learners", "learn_episodes", "battlefield")
        return {k: config[k] for k in kept if k in config}


def pairing_of(record: RunRecord) -> Pairing:
    """The settings of a stored match."""
    return parse_settings(Pairing, record.key.config)  # type: ignore[return-value]


def unit_fields(unit: Unit) -> dict[str, Any]:
    """A unit as stored: ``{"hp": …, "damage": …, "hit_rate": …}``."""
    return asdict(unit)


#: The readings of a match played with the defaults (a tabular learner's γ and
#: tolerance: CMARL-CD's and LA-OCA's own).
DEFAULT_READING = {
    "gamma": BATTLEFIELD_CMARLCD.gamma,
    "tolerance": BATTLEFIELD_CMARLCD.tolerance,
    "unseen": UNSEEN_MODES[0],
    **{kind: unit_fields(unit) for kind, unit in zip(UNIT_KINDS, (MARINE, GUNNER), strict=True)},
}


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

    def pairing(self, pair: tuple[LearnerConfig, LearnerConfig]) -> Pairing:
        """The settings of one pairing's matches (``pair`` as they play)."""
        readings = self.readings
        return Pairing(
            pair,
            self.learn_episodes,
            self.eval_episodes,
            readings.marine,
            readings.gunner,
            readings.unseen,
        )

    def specs(self) -> list[RunSpec]:
        """One spec per (pairing, round); a match's streams depend on its pairing, the
        learning budget, the unit stats and its round (:meth:`Pairing.stream`)."""
        by_name = {config.name: config for config in self.playing}
        specs = []
        for names in pairings(self.algorithms):
            pairing = self.pairing((by_name[names[0]], by_name[names[1]]))
            label = match_label(names)
            specs += [
                RunSpec.make(EXPERIMENT, label, pairing, self.seed, r) for r in range(self.rounds)
            ]
        return specs


def match_label(names: Sequence[str]) -> str:
    """A pairing's name in the store: ``cmarl-cd vs la-oca``."""
    return " vs ".join(names)


# ------------------------------------------------------------------------- runs


def play(pairing: Pairing, seed: np.random.SeedSequence, round_index: int) -> dict[str, Any]:
    """One match: learn, evaluate, and the outcome from each side's view."""
    return play_rounds(pairing, [seed], [round_index])[0]


def play_rounds(
    pairing: Pairing, seeds: Sequence[np.random.SeedSequence], rounds: Sequence[int]
) -> list[dict[str, Any]]:
    """The matches of one pairing in several rounds, learning together
    (:class:`cmarlcd.training.match.MatchBatch`: a deep learner's sides train as one
    stacked model); each plays and stores exactly what it would alone."""
    start = time.perf_counter()
    pair = pairing.learners
    positions = [(0, 1) if r % 2 == 0 else (1, 0) for r in rounds]  # balanced sides
    streams = [[np.random.default_rng(s) for s in seed.spawn(4)] for seed in seeds]
    batch = MatchBatch(
        pairing.rules.spec(),
        pair,
        positions,
        [env for env, _, _, _ in streams],
        [(side0, side1) for _, side0, side1, _ in streams],
        pairing.learn_episodes,
        pairing.unseen,
    )
    batch.learn()
    learn_seconds = (time.perf_counter() - start) / len(seeds)
    results = []
    for match, order, (_, _, _, eval_rng) in zip(batch.matches, positions, streams, strict=True):
        kept = None
        if wanted():  # --save-policies: each team's policy as it is evaluated
            kept = match_policies(match, (pair[order[0]].name, pair[order[1]].name),
                                  pairing.unseen)  # fmt: skip
        evaluated = time.perf_counter()
        result = match.evaluate(pairing.eval_episodes, eval_rng)
        shares = [w / max(1, result.episodes) for w in (*result.wins, result.ties)]
        tags = ("eval/win_rate_side0", "eval/win_rate_side1", "eval/ties")
        scalars = dict(zip(tags, shares, strict=True))
        log_point(len(results), pairing.learn_episodes, scalars, "episodes")  # --log-dir
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
        if kept is not None:
            results[-1][POLICY] = kept
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


def _work(pairing: Pairing) -> float:
    return float(pairing.learn_episodes + pairing.eval_episodes)


def _cost(pairing: Pairing) -> float:
    """Estimated seconds of one match: about 14 µs per episode of two tabular sides, and
    a deep side adds about 8 times that (fitted to the quick preset's measured matches
    on the project's 2-core machine, benchmarks/fit_costs.py): matches with deep sides
    start first."""
    deep = sum(registry.needs_torch(name) for name in pairing.algorithms)
    return 14e-6 * _work(pairing) * (1 + 8 * deep)


def round_of(seed: np.random.SeedSequence) -> int:
    """A match's round: its run index, which :meth:`cmarlcd.runs.RunSpec.seed_sequence`
    puts last in the seed's spawn key."""
    return int(seed.spawn_key[-1])


def run(pairing: Pairing, seed: np.random.SeedSequence) -> dict[str, Any]:
    """The runner's entry for one match."""
    return play(pairing, seed, round_of(seed))


def run_batch(pairing: Pairing, seeds: list[np.random.SeedSequence]) -> list[dict[str, Any]]:
    """The runner's entry for the rounds of one pairing with a deep learner."""
    return play_rounds(pairing, seeds, [round_of(seed) for seed in seeds])


TOURNAMENT = Experiment(
    EXPERIMENT,
    Pairing,
    run=run,
    warm_up=warm_up,
    cost=_cost,
    run_batch=run_batch,
    batchable=lambda pairing: pairing.has_deep,
    work=_work,
    work_unit="episodes",
    uses_device=lambda pairing: pairing.has_deep,
    keeps_policies=lambda pairing: True,
)
