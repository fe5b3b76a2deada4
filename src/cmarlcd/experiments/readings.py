"""Which reading of Section V-B decides the battlefield verdict: a sensitivity study.

The paper leaves four things open on the battlefield (:class:`~.tournament.Readings`).
The study plays one tournament per reading, each changing one choice from the defaults
(:func:`single_readings`), and one per hit rate of both unit kinds (:func:`dial`, a dial
rather than a switch: at 1.0 the game is deterministic). Then it plays the combination
the single changes point to (:func:`combination`). Every tournament is an ordinary one,
stored match by match, so the study resumes, shares the matches no reading changes (two
deep learners meet in the same match under every reading of the tabular learners), and
each of its tournaments is also a section of ``cmarl-cd report``.

Nothing here is tuned toward the paper: every reading tried is reported, with every
claim's verdict and margins, whichever way they point.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

from cmarlcd.errors import require
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.experiments.tournament import Readings, Tournament
from cmarlcd.limits import check_run_count
from cmarlcd.registry import LearnerConfig
from cmarlcd.runs import RunRecord, RunSpec

#: The study's protocol: 10 rounds of 100,000 learning + 100,000 evaluation episodes.
STUDY_ROUNDS = 10
STUDY_EPISODES = 100_000
#: The hit rates of the dial (both unit kinds alike; the defaults are 0.8 and 0.6).
HIT_RATES = (0.6, 0.7, 0.8, 0.9, 1.0)
#: [choice] The other tolerance tried: returns within 1.0 of the record count as reaching
#: it (half the reward of one kill), against the default's 1e-9 (equal up to rounding).
LOOSE_TOLERANCE = 1.0
#: The claim whose margins decide where a reading points (the paper's main claim).
MAIN_CLAIM = claim_checks.CLAIMS[0]


@dataclass(frozen=True)
class Reading:
    """One tournament of the study: its readings, what they change and how."""

    readings: Readings

    @property
    def kind(self) -> str:
        """'default', 'single' (one choice changed), 'hit rate' (the dial: both kinds'
        hit rates alike, nothing else changed) or 'combined'."""
        return kind_of(self.readings)

    @property
    def name(self) -> str:
        """What it changes from the defaults, in a few words."""
        return match_results.reading_label(self.readings.as_reading())


def single_readings() -> list[Reading]:
    """The defaults, then each choice changed alone."""
    return [
        Reading(Readings()),
        Reading(Readings(gamma=0.0)),
        Reading(Readings(tolerance=LOOSE_TOLERANCE)),
        Reading(Readings(unseen="random")),
    ]


def with_hit_rate(readings: Readings, rate: float) -> Readings:
    """``readings`` with both unit kinds hitting at ``rate``."""
    return replace(
        readings,
        marine=replace(readings.marine, hit_rate=rate),
        gunner=replace(readings.gunner, hit_rate=rate),
    )


def dialled(readings: Readings) -> float | None:
    """The hit rate every unit shares when the unit stats differ from the defaults in
    their hit rates alone, else None."""
    return match_results.shared_hit_rate(readings.as_reading())


def dial(rates: Sequence[float] = HIT_RATES) -> list[Reading]:
    """One reading per hit rate of both unit kinds, the rest the defaults."""
    return [Reading(with_hit_rate(Readings(), rate)) for rate in rates]


def main_margin(claims: Sequence[claim_checks.Claim]) -> float:
    """Where a tournament stands on the main claim: the mean over opponents of CMARL-CD's
    win-rate difference (NaN if the claim was not checked)."""
    claim = next(c for c in claims if c.claim == MAIN_CLAIM)
    values = [m.value for m in claim.margins if not math.isnan(m.value)]
    return sum(values) / len(values) if values else math.nan


def combination(scores: Mapping[Reading, float]) -> Reading | None:
    """[choice] The combination the single changes point to: every single change, and the
    best hit rate of the dial, whose main-claim margin (:func:`main_margin`) is above the
    defaults'. None when fewer than two changes point that way (the combination would be
    a tournament already played, or the defaults)."""
    default = next(score for reading, score in scores.items() if reading.kind == "default")
    better = {r: s for r, s in scores.items() if r.kind != "default" and s > default}
    singles = [r for r in better if r.kind == "single"]
    dialled = sorted((r for r in better if r.kind == "hit rate"), key=lambda r: -better[r])
    chosen = singles + dialled[:1]
    if len(chosen) < 2:
        return None
    settings = {
        name: getattr(reading.readings, name)
        for reading in chosen
        for name in changed(reading.readings)
    }
    return Reading(Readings(**settings))


@dataclass(frozen=True)
class ReadingsStudy:
    """The study's tournaments: every one plays ``learners`` with the same protocol."""

    learners: tuple[LearnerConfig, ...]
    rounds: int = STUDY_ROUNDS
    learn_episodes: int = STUDY_EPISODES
    eval_episodes: int = STUDY_EPISODES
    seed: int = 0
    hit_rates: tuple[float, ...] = HIT_RATES

    def __post_init__(self) -> None:
        for rate in self.hit_rates:
            require(0 < rate <= 1, "hit_rates", f"each must be in (0, 1] (got {rate})")
        require(len(set(self.hit_rates)) == len(self.hit_rates), "hit_rates", "each at most once")
        planned = [self.tournament(r) for r in self.first_stage()]  # each one checked
        runs = sum(t.run_count() for t in planned) + planned[0].run_count()  # + combination
        check_run_count(runs, "rounds")

    def first_stage(self) -> list[Reading]:
        """The single changes and the dial, played before the combination is known."""
        return single_readings() + dial(self.hit_rates)

    def tournament(self, reading: Reading) -> Tournament:
        return Tournament(
            self.learners,
            rounds=self.rounds,
            learn_episodes=self.learn_episodes,
            eval_episodes=self.eval_episodes,
            seed=self.seed,
            readings=reading.readings,
        )

    def specs(self, readings: Sequence[Reading]) -> list[RunSpec]:
        """The matches of ``readings``' tournaments, each once (shared matches too)."""
        unique: dict[Any, RunSpec] = {}
        for reading in readings:
            for spec in self.tournament(reading).specs():
                unique.setdefault(spec.key, spec)
        return list(unique.values())


@dataclass(frozen=True)
class Outcome:
    """One tournament of the study, summarised."""

    reading: Reading
    records: list[RunRecord]
    cells: list[match_results.Cell]
    claims: list[claim_checks.Claim]

    @property
    def score(self) -> float:
        return main_margin(self.claims)


def outcome(reading: Reading, records: Sequence[RunRecord]) -> Outcome:
    """The cells and claims of one reading's stored matches."""
    cells = match_results.summarize(records)
    return Outcome(reading, list(records), cells, claim_checks.check_claims(records, cells))


def records_of(study: ReadingsStudy, reading: Reading, stored: Mapping[Any, RunRecord]) -> list:
    """The stored matches of one reading's tournament."""
    return [stored[s.key] for s in study.tournament(reading).specs() if s.key in stored]


# ------------------------------------------------------------ from the store


def readings_from(reading: Mapping[str, Any]) -> Readings | None:
    """The :class:`Readings` of a stored tournament (:func:`match_results.match_reading`), or None
    when its tabular learners were given different settings (the Python API allows it;
    no study does it)."""
    if isinstance(reading["gamma"], list) or isinstance(reading["tolerance"], list):
        return None
    default = tour.DEFAULT_READING

    def own(name: str) -> Any:
        value = reading[name]
        return None if value is None or value == default[name] else value

    return Readings(
        gamma=own("gamma"),
        tolerance=own("tolerance"),
        unseen=reading["unseen"] or default["unseen"],
        marine=tour.Unit(**reading["marine"]),
        gunner=tour.Unit(**reading["gunner"]),
    )


def changed(readings: Readings) -> list[str]:
    """The settings of ``readings`` that differ from the defaults, in field order."""
    default = Readings()
    names = [f.name for f in fields(Readings)]
    return [name for name in names if getattr(readings, name) != getattr(default, name)]


def kind_of(readings: Readings) -> str:
    """See :attr:`Reading.kind`."""
    names = changed(readings)
    if not names:
        return "default"
    if dialled(readings) is not None and set(names) <= set(tour.UNIT_KINDS):
        return "hit rate"
    return "single" if len(names) == 1 else "combined"


def stored_studies(groups: Sequence[Sequence[RunRecord]]) -> list[list[Outcome]]:
    """Stored tournaments (:func:`match_results.tournaments`) that form a study: two or more
    readings with the same seed and budgets. Each study lists its tournaments in the
    order defaults, single changes, the dial by hit rate, combinations."""
    by_protocol: dict[tuple, list[tuple[Readings, Sequence[RunRecord]]]] = {}
    for records in groups:
        readings = readings_from(match_results.match_reading(records))
        if readings is not None and _at_battlefield_settings(records):
            key = match_results.protocol_key(records[0])[:3]
            by_protocol.setdefault(key, []).append((readings, records))
    studies = [
        [outcome(Reading(readings), records) for readings, records in found]
        for found in by_protocol.values()
        if len(found) >= 2
    ]
    return [sorted(found, key=_place) for found in studies]


def _at_battlefield_settings(records: Sequence[RunRecord]) -> bool:
    """Whether every side of a stored tournament plays with its battlefield settings,
    readings aside (a tournament of other settings, ``--set``, is not a reading of the
    study: it is reported on its own, its sides named with their settings)."""
    return not any(
        match_results.changed_settings(learner)
        for rec in records
        for learner in tour.pairing_of(rec).learners
    )


def _place(found: Outcome) -> tuple:
    """Defaults, single changes (in field order: γ, tolerance, unseen, units), the dial by
    hit rate, then combinations."""
    kinds = ("default", "single", "hit rate", "combined")
    readings = found.reading.readings
    order = [f.name for f in fields(Readings)]
    which = [order.index(name) for name in changed(readings)]
    return (kinds.index(found.reading.kind), dialled(readings) or 0.0, which, found.reading.name)
