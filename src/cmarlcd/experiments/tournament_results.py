"""Stored battlefield matches read back: which tournament each belongs to (seed, budgets,
readings), and per (algorithm, opponent) its win, loss and tie rates and win steps over
rounds (Figs. 6-7).

Per (algorithm, opponent) and round: the rates of the algorithm's side over the
evaluation episodes, and its *win steps* (the mean turns of its won episodes, undefined
in a round it won none), reported as mean and spread (population standard deviation)
over rounds. In self-play the rates are the mean of the algorithm's two sides.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from itertools import combinations, product
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments.tournament import (
    DEFAULT_READING,
    STD_DDOF,
    UNIT_KINDS,
    Pairing,
    battlefield_learners,
    is_tabular,
    pairing_of,
    unit_fields,
)
from cmarlcd.runs import RunRecord


def reading_of(pairing: Pairing) -> dict[str, Any]:
    """The readings a stored pairing was played under: the tabular learners' discount and
    tolerance and what they play in unseen states (None when it has no tabular side),
    and the unit stats."""
    tabular = [learner for learner in pairing.learners if is_tabular(learner)]

    def one(name: str) -> Any:
        values = sorted({getattr(learner, name) for learner in tabular})
        return None if not values else values[0] if len(values) == 1 else values

    return {
        "gamma": one("gamma"),
        "tolerance": one("tolerance"),
        "unseen": pairing.unseen if tabular else None,
        **{kind: unit_fields(getattr(pairing, kind)) for kind in UNIT_KINDS},
    }


def match_reading(records: Sequence[RunRecord]) -> dict[str, Any]:
    """The readings of one tournament's matches (:func:`tournaments`): a tabular
    learners' setting that differs among them is the list of its values; a tournament
    of deep learners alone has no tabular readings (None)."""
    readings = [reading_of(pairing_of(rec)) for rec in records]
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
    pairing = pairing_of(record)
    units = tuple(tuple(unit_fields(getattr(pairing, kind)).values()) for kind in UNIT_KINDS)
    return (record.key.root_seed, pairing.learn_episodes, pairing.eval_episodes, units)


def tabular_settings(pairing: Pairing) -> dict[str, tuple[float, float]]:
    """Each tabular learner's (γ, tolerance) in a stored pairing."""
    return {
        learner.name: (float(learner.gamma), float(learner.tolerance))
        for learner in pairing.learners
        if is_tabular(learner)
    }


def tabular_key(record: RunRecord) -> tuple | None:
    """The tabular readings of a match: what its tabular sides play in unseen states and
    the (γ, tolerance) they all share, or each one's when they differ (possible from the
    Python API only); None for a match of two deep learners."""
    pairing = pairing_of(record)
    settings = tabular_settings(pairing)
    if not settings:
        return None
    shared = set(settings.values())
    each = ("all", *shared.pop()) if len(shared) == 1 else ("each", *sorted(settings.items()))
    return (pairing.unseen, each)


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
                    if all(own.get(n) == other[1:] for n in tabular_settings(pairing_of(rec)))
                ]
        groups[(unseen, shared)] = recs
    found = []
    for recs in groups.values():
        names = {name for rec in recs for name in pairing_of(rec).algorithms}
        found.append(recs + [r for r in deep_only if set(pairing_of(r).algorithms) <= names])
    if deep_only:
        found.append(deep_only)
    found = [variant for group in found for variant in _one_setting_each(group)]
    unique = {frozenset(rec.key for rec in group): group for group in found}  # one of each
    keys, found = list(unique), list(unique.values())
    kept = [g for g, k in zip(found, keys, strict=True) if not any(k < other for other in keys)]
    return sorted(kept, key=lambda g: reading_label(match_reading(g)) != "defaults")


#: Settings a tabular learner's side is told apart by as a *reading* of the tournament
#: (:func:`tabular_key`, the section's title), not in its name.
READING_SETTINGS = ("gamma", "tolerance")


def _reference(learner: Any) -> tuple[Any, tuple[str, ...]]:
    """What a side is told apart from: its battlefield settings, readings aside."""
    ignore = READING_SETTINGS if is_tabular(learner) else ()
    return battlefield_learners().get(learner.name), ignore


def changed_settings(learner: Any) -> dict[str, Any]:
    """A side's settings that differ from its battlefield settings, readings aside."""
    return registry.changed_settings(learner, *_reference(learner))


def side_label(learner: Any) -> str:
    """How the tables name a side: ``"CMARL-CD"``, or with the settings that differ from
    its battlefield settings, readings aside (``"VDN (lr=0.001)"``)."""
    return registry.variant_label(learner, *_reference(learner))


def _side_settings(record: RunRecord) -> dict[str, str]:
    return {
        learner.name: json.dumps(changed_settings(learner), sort_keys=True, default=str)
        for learner in pairing_of(record).learners
    }


def _one_setting_each(group: list[RunRecord]) -> list[list[RunRecord]]:
    """A tournament in which an algorithm plays with two settings (``--set`` of two
    sweeps on one store) split into tournaments in which each plays with one: for each
    choice of settings, the matches it allows among each largest set of algorithms that
    met each other there (a match is in every one it fits; groups that another one
    contains are dropped by the caller). Runs of different settings never share a cell."""
    sides = [(rec, _side_settings(rec)) for rec in group]
    played: dict[str, set[str]] = defaultdict(set)
    for _, settings in sides:
        for name, setting in settings.items():
            played[name].add(setting)
    if all(len(settings) == 1 for settings in played.values()):
        return [group]
    names = sorted(played)
    split = []
    for choice in product(*(sorted(played[name]) for name in names)):
        chosen = dict(zip(names, choice, strict=True))
        recs = [r for r, own in sides if all(chosen[n] == s for n, s in own.items())]
        for algorithms in _complete_sets(recs):
            split.append([r for r in recs if set(pairing_of(r).algorithms) <= algorithms])
    return split


def _complete_sets(records: Sequence[RunRecord]) -> list[set[str]]:
    """The largest sets of algorithms in which every two played each other in
    ``records`` (a tournament's pairings are all there)."""
    names = sorted({name for rec in records for name in pairing_of(rec).algorithms})
    met = {frozenset(pairing_of(rec).algorithms) for rec in records}
    found: list[set[str]] = []
    for size in range(len(names), 0, -1):
        for subset in combinations(names, size):
            complete = all(frozenset(pair) in met for pair in combinations(subset, 2))
            if complete and not any(set(subset) <= larger for larger in found):
                found.append(set(subset))
    return found


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
        pair: {r: {m: finite_mean([v[m] for v in vs]) for m in METRICS} for r, vs in rounds.items()}
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


def finite_mean(values: Sequence[float]) -> float:
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
