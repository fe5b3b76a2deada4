"""The tournament's bookkeeping: pairings, sides, rates over rounds, the claims."""

from __future__ import annotations

import json
import math

import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.experiments import settings_of
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.sweeps.store import RunKey, RunRecord


def test_a_round_of_four_algorithms_has_ten_matches_with_self_play_once() -> None:
    names = ("cmarl-cd", "la-oca", "qmix", "vdn")
    matches = tour.pairings(names)
    assert len(matches) == 10
    assert sorted(a for a, b in matches if a == b) == sorted(names)  # each against itself once
    pairs = [frozenset(m) for m in matches if m[0] != m[1]]
    assert len(set(pairs)) == len(pairs) == 6


def test_specs_one_match_per_pairing_and_round() -> None:
    learners = tuple(tour.battlefield_learners()[n] for n in tour.TABULAR)
    contest = tour.Tournament(learners, rounds=3, learn_episodes=10, eval_episodes=10)
    specs = contest.specs()
    assert len(specs) == 3 * 3
    assert {s.algorithm for s in specs} == {
        "cmarl-cd vs cmarl-cd",
        "cmarl-cd vs la-oca",
        "la-oca vs la-oca",
    }
    assert len({s.key for s in specs}) == len(specs)
    seeds = {s.seed_sequence().generate_state(2).tobytes() for s in specs}
    assert len(seeds) == len(specs)  # every match has streams of its own


@pytest.mark.parametrize(
    ("field", "value"),
    [("rounds", 0), ("learn_episodes", 0), ("eval_episodes", 0), ("seed", -1)],
)
def test_bad_settings_are_rejected(field, value) -> None:
    learners = (tour.battlefield_learners()["cmarl-cd"],)
    with pytest.raises(ConfigError, match=field):
        tour.Tournament(learners, **{field: value})


@pytest.mark.slow
def test_sides_alternate_over_rounds_and_are_recorded() -> None:
    config = tour.Tournament(
        (tour.battlefield_learners()["cmarl-cd"], tour.battlefield_learners()["la-oca"]),
        rounds=2,
        learn_episodes=5,
        eval_episodes=5,
    ).specs()[3]  # the cmarl-cd vs la-oca matches come after the two self-play rounds
    assert config.algorithm == "cmarl-cd vs la-oca"
    sides = []
    for round_index in (0, 1):
        metrics = tour.play(settings_of(config), config.seed_sequence(), round_index)
        sides.append(metrics["sides"])
        assert sum(metrics["wins"]) + metrics["ties"] == metrics["episodes"] == 5
    assert sides == [["cmarl-cd", "la-oca"], ["la-oca", "cmarl-cd"]]


def record(pair: str, round_index: int, **metrics) -> RunRecord:
    config = {"learn_episodes": 1, "eval_episodes": metrics["episodes"]}
    key = RunKey("tournament", pair, json.dumps(config), 0, round_index)
    return RunRecord(key=key, metrics=metrics, wall_seconds=0.0)


def match(pair, round_index, sides, wins, ties, win_turns, episodes=100) -> RunRecord:
    return record(
        pair,
        round_index,
        sides=sides,
        wins=wins,
        ties=ties,
        win_turns=win_turns,
        episodes=episodes,
    )


def test_rates_and_win_steps_per_opponent_over_rounds() -> None:
    records = [
        # round 0: a on side 0 wins 60 (300 turns), b wins 30 (240 turns), 10 ties
        match("a vs b", 0, ["a", "b"], [60, 30], 10, [300, 240]),
        # round 1: sides swapped; a wins 50 (350 turns), b wins 40 (200 turns)
        match("a vs b", 1, ["b", "a"], [40, 50], 10, [200, 350]),
        # self-play: each side of a is a, their mean
        match("a vs a", 0, ["a", "a"], [45, 35], 20, [90, 140]),
    ]
    cells = {(c.algorithm, c.opponent): c for c in match_results.summarize(records, ["a", "b"])}
    ab, ba, aa = cells[("a", "b")], cells[("b", "a")], cells[("a", "a")]
    assert ab.rounds == 2 and ab.win_rate == pytest.approx(0.55)
    assert ab.win_rate_std == pytest.approx(0.05)
    assert ab.loss_rate == pytest.approx(0.35) and ab.tie_rate == pytest.approx(0.10)
    assert ab.win_steps == pytest.approx((5 + 7) / 2) and ab.win_steps_std == pytest.approx(1)
    assert ba.win_rate == pytest.approx(0.35) and ba.win_steps == pytest.approx((8 + 5) / 2)
    assert aa.win_rate == pytest.approx(0.40) and aa.loss_rate == pytest.approx(0.40)
    assert aa.tie_rate == pytest.approx(0.20) and aa.win_steps == pytest.approx((2 + 4) / 2)


def test_a_round_without_wins_has_no_win_steps() -> None:
    records = [match("a vs b", 0, ["a", "b"], [0, 90], 10, [0, 450])]
    cells = {(c.algorithm, c.opponent): c for c in match_results.summarize(records, ["a", "b"])}
    assert math.isnan(cells[("a", "b")].win_steps)
    assert cells[("a", "b")].to_dict()["win_steps"] is None


def test_claims_say_supported_contradicted_or_not_checked() -> None:
    records = []
    for r in range(4):  # CMARL-CD wins 70-75 %, LA-OCA 20-25 %, in every round
        records.append(
            match(
                "cmarl-cd vs la-oca",
                r,
                ["cmarl-cd", "la-oca"],
                [70 + r, 25 - r],
                5,
                [4 * (70 + r), 9 * (25 - r)],
            )
        )
    cells = match_results.summarize(records, ["cmarl-cd", "la-oca"])
    claims = {c.claim: c for c in claim_checks.check_claims(records, cells)}
    beats = claims["CMARL-CD has the higher win rate against every other algorithm"]
    assert beats.verdict == "supported" and "71.5%" in beats.evidence
    assert claims["CMARL-CD needs the fewest win steps"].verdict == "supported"
    assert claims["QMIX beats LA-OCA"].verdict == "not checked"
    flipped = [
        match(
            "cmarl-cd vs la-oca",
            r,
            ["la-oca", "cmarl-cd"],
            [70 + r, 25 - r],
            5,
            [4 * (70 + r), 9 * (25 - r)],
        )
        for r in range(4)
    ]
    cells = match_results.summarize(flipped, ["cmarl-cd", "la-oca"])
    claims = {c.claim: c for c in claim_checks.check_claims(flipped, cells)}
    assert claims["CMARL-CD has the higher win rate against every other algorithm"].verdict == (
        "contradicted"
    )
    assert claims["CMARL-CD needs the fewest win steps"].verdict == "contradicted"


@pytest.mark.slow
def test_rounds_learning_together_store_what_they_store_alone() -> None:
    pytest.importorskip("torch")
    learners = (tour.battlefield_learners()["vdn"], tour.battlefield_learners()["cmarl-cd"])
    contest = tour.Tournament(learners, rounds=2, learn_episodes=30, eval_episodes=30)
    specs = [s for s in contest.specs() if s.algorithm == "vdn vs cmarl-cd"]
    together = tour.run_batch(settings_of(specs[0]), [s.seed_sequence() for s in specs])
    alone = [
        tour.run(settings_of(s), s.seed_sequence()) for s in specs
    ]  # fresh seeds: spawn counts
    timing = {"seconds", "learn_seconds"}
    for a, b in zip(together, alone, strict=True):
        assert {k: v for k, v in a.items() if k not in timing} == {
            k: v for k, v in b.items() if k not in timing
        }
    assert [m["sides"] for m in together] == [["vdn", "cmarl-cd"], ["cmarl-cd", "vdn"]]
    assert settings_of(specs[0]).has_deep


@pytest.mark.parametrize(
    ("qmix_wins", "verdict"),
    [
        ((50, 52, 51, 49), "contradicted"),  # 50.5 %, 40 % lies > 2 SE below
        ((30, 32, 31, 29), "supported"),  # 30.5 %, 40 % lies > 2 SE above
        ((30, 50, 35, 45), "not separated"),  # 40 % ± 4.6 % x 2: within the noise
    ],
)
def test_under_40_percent_is_a_margin_with_its_standard_error(qmix_wins, verdict) -> None:
    records = [
        match("cmarl-cd vs qmix", r, ["qmix", "cmarl-cd"], [w, 90 - w], 10, [6 * w, 0])
        for r, w in enumerate(qmix_wins)
    ]
    cells = match_results.summarize(records, ["cmarl-cd", "qmix"])
    claims = {c.claim: c for c in claim_checks.check_claims(records, cells)}
    claim = claims["QMIX wins under 40 % against CMARL-CD"]
    assert claim.verdict == verdict
    (margin,) = claim.margins
    rates = [w / 100 for w in qmix_wins]
    assert margin.value == pytest.approx(0.4 - sum(rates) / 4)
    assert margin.standard_error == pytest.approx(
        math.sqrt(sum((x - sum(rates) / 4) ** 2 for x in rates) / 3) / 2
    )
    assert claims["VDN wins under 40 % against CMARL-CD"].verdict == "not checked"


# ------------------------------------------------ two settings of one algorithm


def _played(names: str, **changes: dict) -> list[RunRecord]:
    """The (metric-less) matches of a 1-round tournament of ``names``, each learner with
    the settings ``changes`` gives it (``--set``)."""
    from dataclasses import replace

    known = tour.battlefield_learners()
    learners = tuple(replace(known[n], **changes.get(n, {})) for n in names.split(","))
    specs = tour.Tournament(learners, 1, 100, 100, 0).specs()
    return [RunRecord(spec.key, {}, 0.0) for spec in specs]


def _found(*sweeps: list[RunRecord]) -> list[list[str]]:
    """Each stored tournament as its sides' labels, sorted."""
    records = list({rec.key: rec for sweep in sweeps for rec in sweep}.values())
    found = []
    for group in match_results.tournaments(records):
        sides = {
            match_results.side_label(learner)
            for rec in group
            for learner in tour.pairing_of(rec).learners
        }
        found.append(sorted(sides))
    return sorted(found)


DELTA = {"cmarl-cd": {"delta": 0.08}}


def test_a_second_setting_of_an_algorithm_is_a_tournament_of_its_own() -> None:
    """The same algorithms twice, CMARL-CD's delta changed the second time: two
    tournaments, each with one CMARL-CD, sharing LA-OCA's self-play."""
    first, second = _played("cmarl-cd,la-oca"), _played("cmarl-cd,la-oca", **DELTA)
    assert _found(first, second) == [
        ["CMARL-CD", "LA-OCA"],
        ["CMARL-CD (delta=0.08)", "LA-OCA"],
    ]


def test_a_second_setting_played_by_fewer_algorithms_is_not_left_out() -> None:
    """Three algorithms at their settings, then two with CMARL-CD's delta changed: the
    second sweep is its own tournament of two (it was left out of every one)."""
    first = _played("cmarl-cd,la-oca,vdn")
    second = _played("cmarl-cd,la-oca", **DELTA)
    assert _found(first, second) == [
        ["CMARL-CD", "LA-OCA", "VDN"],
        ["CMARL-CD (delta=0.08)", "LA-OCA"],
    ]


def test_a_second_setting_of_a_deep_algorithm_keeps_its_opponents() -> None:
    """VDN with another learning rate against CMARL-CD only: a tournament of CMARL-CD and
    that VDN (not VDN's self-play alone)."""
    first = _played("cmarl-cd,la-oca,vdn")
    second = _played("cmarl-cd,vdn", vdn={"lr": 0.0123})
    assert _found(first, second) == [
        ["CMARL-CD", "LA-OCA", "VDN"],
        ["CMARL-CD", "VDN (lr=0.0123)"],
    ]
