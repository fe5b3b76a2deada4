"""Which reading of Section V-B decides the battlefield verdict: a sensitivity study.

The paper leaves four things open on the battlefield (:class:`~.tournament.Readings`).
The study plays one tournament per reading that changes one switch from the defaults
(:func:`single_readings`), and turns two of the choices as dials rather than switches:
the hit rate of both unit kinds (:func:`dial`; at 1.0 the game is deterministic) and the
discount γ of the tabular learners (:func:`gamma_dial`: from each turn's own reward at 0
to a record that looks about ten turns ahead at 0.9), the latter at the default unit
stats and again at the hit rate the first dial favours (:meth:`ReadingsStudy.second_stage`).
Then it plays the combination the dials and switches point to (:func:`combination`).
Every tournament is an ordinary one,
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
#: The discounts of the γ dial (CMARL-CD and LA-OCA alike; their default is 0.9), spaced
#: about evenly on a log scale from 0.01, with 0 (each turn's own reward) below them.
GAMMAS = (0.0, 0.01, 0.03, 0.1, 0.3, 0.9)
#: The kinds of tournament of a study (:attr:`Reading.kind`), in the order it reports them.
KINDS = ("default", "single", "hit rate", "gamma", "combined")
#: The kinds that are points of a dial (γ and the hit rate: :func:`dial_point`).
DIAL_KINDS = ("default", "hit rate", "gamma")
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
        """'default', 'single' (one switch changed), 'hit rate' (the hit-rate dial: both
        kinds' hit rates alike, nothing else changed), 'gamma' (the γ dial: the tabular
        learners' discount changed, and at most the hit rate of both kinds alike) or
        'combined'."""
        return kind_of(self.readings)

    @property
    def name(self) -> str:
        """What it changes from the defaults, in a few words."""
        return match_results.reading_label(self.readings.as_reading())


def single_readings() -> list[Reading]:
    """The defaults, then each switch changed alone (γ = 0, the reading of the paper's
    words, is a point of the γ dial, :func:`gamma_dial`)."""
    return [
        Reading(Readings()),
        Reading(Readings(tolerance=LOOSE_TOLERANCE)),
        Reading(Readings(unseen="random")),
    ]


def with_gamma(readings: Readings, gamma: float) -> Readings:
    """``readings`` with the tabular learners' discount at ``gamma`` (their own default
    kept as the default, so γ = 0.9 is the same reading as no γ at all)."""
    return replace(readings, gamma=None if gamma == tour.DEFAULT_READING["gamma"] else gamma)


def gamma_dial(gammas: Sequence[float] = GAMMAS, hit_rate: float | None = None) -> list[Reading]:
    """One reading per discount of the tabular learners, at the default unit stats or
    with every unit hitting at ``hit_rate``."""
    base = Readings() if hit_rate is None else with_hit_rate(Readings(), hit_rate)
    return [Reading(with_gamma(base, gamma)) for gamma in gammas]


def check_gammas(gammas: Sequence[float]) -> None:
    """The γ dial's discounts: at least one, each in [0, 1) and given once."""
    require(len(gammas) > 0, "gammas", "give at least one discount")
    for gamma in gammas:
        ok = math.isfinite(gamma) and 0 <= gamma < 1
        require(ok, "gammas", f"each must be in [0, 1) (got {gamma:g})")
    require(len(set(gammas)) == len(gammas), "gammas", "each at most once")


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


def _ranked(score: float) -> float:
    """A score to rank by: an unchecked claim (NaN) below every number."""
    return -math.inf if math.isnan(score) else score


def favoured_hit_rate(scores: Mapping[Reading, float]) -> float | None:
    """The hit rate of the hit-rate dial's tournament with the highest main-claim margin
    (:func:`main_margin`; on a tie the first played, the lower hit rate), or None when
    the dial was not played or none of its tournaments checked the claim."""
    checked = [r for r in scores if r.kind == "hit rate" and not math.isnan(scores[r])]
    if not checked:
        return None
    return dialled(max(checked, key=lambda r: scores[r]).readings)


def best_dial_point(scores: Mapping[Reading, float]) -> Reading:
    """The tournament of the dials (the defaults, the hit-rate dial, the γ dial at each
    hit rate it was played at) with the highest main-claim margin; on a tie the first
    played. An unchecked claim (NaN) ranks below every number."""
    points = [r for r in scores if r.kind in DIAL_KINDS]
    return max(points, key=lambda r: _ranked(scores[r]))


def pointed_to(scores: Mapping[Reading, float]) -> Reading | None:
    """[choice] The reading the study points to: the best point of the dials
    (:func:`best_dial_point`: its γ and hit rate), with every single switch whose
    tournament's main-claim margin is above the defaults' (on the point estimates: no
    threshold of standard errors). None when the defaults' margin is unknown (not played,
    or the claim not checked): nothing can be said to help."""
    default = [score for reading, score in scores.items() if reading.kind == "default"]
    if not default or math.isnan(default[0]):
        return None
    point = best_dial_point(scores)
    switches = [r for r, s in scores.items() if r.kind == "single" and s > default[0]]
    settings = {
        name: getattr(reading.readings, name)
        for reading in (point, *switches)
        for name in changed(reading.readings)
    }
    return Reading(Readings(**settings))


def combination(scores: Mapping[Reading, float]) -> Reading | None:
    """The reading the study points to (:func:`pointed_to`) when it is a tournament not
    played yet (a combination of a dial's point and one or more switches), else None."""
    reading = pointed_to(scores)
    return None if reading is None or reading in scores else reading


@dataclass(frozen=True)
class ReadingsStudy:
    """The study's tournaments: every one plays ``learners`` with the same protocol."""

    learners: tuple[LearnerConfig, ...]
    rounds: int = STUDY_ROUNDS
    learn_episodes: int = STUDY_EPISODES
    eval_episodes: int = STUDY_EPISODES
    seed: int = 0
    hit_rates: tuple[float, ...] = HIT_RATES
    gammas: tuple[float, ...] = GAMMAS

    def __post_init__(self) -> None:
        for rate in self.hit_rates:
            require(0 < rate <= 1, "hit_rates", f"each must be in (0, 1] (got {rate})")
        require(len(set(self.hit_rates)) == len(self.hit_rates), "hit_rates", "each at most once")
        check_gammas(self.gammas)
        planned = [self.tournament(r) for r in self.first_stage()]  # each one checked
        again = [r for r in gamma_dial(self.gammas) if r.kind == "gamma"]  # γ 0.9: played
        later = (len(again) if self.hit_rates and self.has_tabular else 0) + 1  # + combination
        runs = sum(t.run_count() for t in planned) + later * planned[0].run_count()
        check_run_count(runs, "rounds")

    @property
    def has_tabular(self) -> bool:
        """Whether a tabular learner plays (the γ dial turns their discount only)."""
        return any(tour.is_tabular(learner) for learner in self.learners)

    def first_stage(self) -> list[Reading]:
        """The switches, the hit-rate dial and the γ dial at the default unit stats (when
        a tabular learner plays), each tournament once (γ = 0.9 is the defaults)."""
        gammas = gamma_dial(self.gammas) if self.has_tabular else []
        return list(dict.fromkeys(single_readings() + dial(self.hit_rates) + gammas))

    def second_stage(self, scores: Mapping[Reading, float]) -> list[Reading]:
        """The γ dial again at the hit rate the first stage's dial favours
        (:func:`favoured_hit_rate`), less the tournaments already played; none without a
        tabular learner, or when no tournament of the hit-rate dial checked the claim."""
        rate = favoured_hit_rate(scores)
        if rate is None or not self.has_tabular:
            return []
        return [r for r in gamma_dial(self.gammas, rate) if r not in scores]

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


@dataclass(frozen=True)
class DialMargin:
    """One point of the γ dial's figure: a tabular learner's paired margin against one
    opponent (:func:`~.tournament_claims.paired_margin`: per round, its win rate minus the
    opponent's) in the tournament at (γ, hit rate)."""

    learner: str
    opponent: str
    gamma: float
    hit_rate: float | None
    """The hit rate every unit shares; None for the default unit stats."""
    margin: claim_checks.Margin

    def to_dict(self) -> dict[str, Any]:
        finite = {
            k: (v if math.isfinite(v) else None)
            for k, v in (
                ("margin", self.margin.value),
                ("standard_error", self.margin.standard_error),
            )
        }
        return {
            "learner": self.learner,
            "opponent": self.opponent,
            "gamma": self.gamma,
            "hit_rate": self.hit_rate,
            **finite,
            "rounds": self.margin.rounds,
        }


def gamma_margins(outcomes: Sequence[Outcome]) -> list[DialMargin]:
    """The γ dial from a study's tournaments: at each hit rate the γ dial was played at
    (None: the default unit stats), every tournament on the dials there (the defaults or
    the hit-rate dial's give its γ = 0.9 point), each tabular learner's margin against
    each other algorithm. Read from the tournaments' stored matches only."""
    points = {dial_point(o.reading.readings): o for o in outcomes}
    points.pop(None, None)
    rates = {dialled(o.reading.readings) for o in outcomes if o.reading.kind == "gamma"}
    found = []
    for (gamma, rate), o in sorted(points.items(), key=lambda item: _point_order(item[0])):
        if rate not in rates:
            continue
        names = [c.algorithm for c in o.cells if c.algorithm == c.opponent]
        for learner in (n for n in names if n in tour.TABULAR):
            for opponent in (n for n in names if n != learner):
                margin = claim_checks.paired_margin(o.records, learner, opponent)
                found.append(DialMargin(learner, opponent, gamma, rate, margin))
    return found


def _point_order(point: tuple[float, float | None]) -> tuple:
    gamma, rate = point
    return (rate is not None, rate or 0.0, gamma)


def tournament_options(readings: Readings) -> list[str]:
    """The options of ``cmarl-cd tournament`` that play ``readings`` (none for the
    defaults)."""
    options = []
    for name in changed(readings):
        value = getattr(readings, name)
        if name in tour.UNIT_KINDS:
            options += [f"--{name}", f"{value.hp},{value.damage},{_number(value.hit_rate)}"]
        else:
            options += [f"--{name}", value if isinstance(value, str) else _number(value)]
    return options


def _number(value: float) -> str:
    """A number as the shortest text that reads back as it (``0.1``, ``1``, not
    ``0.1000000000000000055``, nor ``0.123457`` for 0.1234567)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


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
    names = set(changed(readings))
    units = names & set(tour.UNIT_KINDS)
    if not names:
        return "default"
    if names <= {"gamma", *tour.UNIT_KINDS} and (not units or dialled(readings) is not None):
        return "gamma" if "gamma" in names else "hit rate"
    return "single" if len(names) == 1 else "combined"


def dial_point(readings: Readings) -> tuple[float, float | None] | None:
    """Where a reading sits on the dials: (the tabular learners' γ, the hit rate every
    unit shares or None for the default unit stats), or None for a reading that changes
    anything else."""
    if kind_of(readings) not in DIAL_KINDS:
        return None
    gamma = tour.DEFAULT_READING["gamma"] if readings.gamma is None else readings.gamma
    return (gamma, dialled(readings))


def stored_studies(groups: Sequence[Sequence[RunRecord]]) -> list[list[Outcome]]:
    """Stored tournaments (:func:`match_results.tournaments`) that form a study: two or more
    readings with the same seed and budgets. Each study lists its tournaments in the
    order of :func:`_place`."""
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
    """Defaults, single switches (in field order: tolerance, unseen, one unit kind's
    stats), the hit-rate dial by hit rate, the γ dial by hit rate (the default unit stats
    first) then γ, then combinations."""
    readings = found.reading.readings
    order = [f.name for f in fields(Readings)]
    which = [order.index(name) for name in changed(readings)]
    gamma = -1.0 if readings.gamma is None else readings.gamma
    where = (dialled(readings) or 0.0, gamma)
    return (KINDS.index(found.reading.kind), where, which, found.reading.name)
