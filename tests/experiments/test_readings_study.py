"""The battlefield readings study: which tournaments it plays, the combination the single
changes point to, its table read back from the store, and the command end to end."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cmarlcd.cli import app
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import readings as study
from cmarlcd.experiments import settings_of
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments.tournament import Readings, Unit
from cmarlcd.learners.tabular.automata import LAOCA
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic
from cmarlcd.reports.readings import _pointed_text, _pointed_to, margin_text

LEARNERS = tour.battlefield_learners()


def test_each_single_reading_changes_one_choice_and_the_dial_only_hit_rates() -> None:
    default = Readings()
    singles = study.single_readings()
    assert singles[0].readings == default and singles[0].kind == "default"
    for reading in singles[1:]:
        changed = [
            name
            for name in ("gamma", "tolerance", "unseen", "marine", "gunner")
            if getattr(reading.readings, name) != getattr(default, name)
        ]
        assert len(changed) == 1 and reading.kind == "single"
    assert [r.name for r in singles[1:]] == ["tolerance = 1", "unseen states: random"]
    for rate, reading in zip(study.HIT_RATES, study.dial(), strict=True):
        units = (reading.readings.marine, reading.readings.gunner)
        assert units == (Unit(3, 1, rate), Unit(6, 2, rate)) and reading.kind == "hit rate"
        assert reading.name == f"hit rate {rate:g}"
    assert study.Reading(Readings(marine=Unit(3, 1, 0.7))).kind == "single"  # one kind only


def test_the_gamma_dial_changes_the_discount_alone_at_each_hit_rate() -> None:
    at_defaults = study.gamma_dial((0.0, 0.03, 0.9))
    assert [r.name for r in at_defaults] == ["γ = 0", "γ = 0.03", "defaults"]
    assert [r.kind for r in at_defaults] == ["gamma", "gamma", "default"]
    assert at_defaults[2] == study.single_readings()[0]  # γ 0.9 is the learners' own
    at_high = study.gamma_dial((0.1, 0.9), hit_rate=0.9)
    assert [r.name for r in at_high] == ["γ = 0.1; hit rate 0.9", "hit rate 0.9"]
    assert at_high[0].kind == "gamma" and at_high[1] == study.dial((0.9,))[0]
    assert study.dial_point(at_high[0].readings) == (0.1, 0.9)
    assert study.dial_point(at_defaults[2].readings) == (0.9, None)
    assert study.dial_point(Readings(gamma=0.1, unseen="random")) is None  # a combination
    assert study.Reading(Readings(gamma=0.1, unseen="random")).kind == "combined"
    # a γ with one unit kind's hit rate changed is no point of the dials
    assert study.Reading(Readings(gamma=0.1, marine=Unit(3, 1, 0.7))).kind == "combined"


def named(*readings: Readings) -> list[study.Reading]:
    return [study.Reading(r) for r in readings]


def test_the_study_points_to_the_dials_best_point_and_every_switch_that_helped() -> None:
    default, loose, unseen = study.single_readings()
    low, high = study.dial((0.6, 1.0))
    myopic, near = study.gamma_dial((0.0, 0.3))
    (high_myopic,) = study.gamma_dial((0.0,), hit_rate=1.0)
    scores = {default: -0.20, loose: -0.19, unseen: -0.25, low: -0.15, high: 0.1}
    scores |= {myopic: -0.1, near: math.nan, high_myopic: 0.15}
    # the dial's best point (γ 0 at hit rate 1) and the loose tolerance, which helped;
    # random targets did not, and an unchecked claim (NaN) ranks below every number
    assert study.favoured_hit_rate(scores) == 1.0
    assert study.best_dial_point(scores) == high_myopic
    combined = study.combination(scores)
    assert combined.readings == study.with_hit_rate(Readings(gamma=0.0, tolerance=1.0), 1.0)
    assert combined.kind == "combined" and combined.name == "γ = 0; tolerance = 1; hit rate 1"
    # no switch helped: the study points to the dial's best point, already played
    no_switch = {**scores, loose: -0.3}
    assert study.pointed_to(no_switch) == high_myopic and study.combination(no_switch) is None
    # the defaults may be the best point of all
    worse = {default: 0.0, loose: 0.05, unseen: -0.1, low: -0.1, high: -0.3, myopic: -0.2}
    assert study.pointed_to(worse) == loose and study.combination(worse) is None


def test_the_gamma_dial_is_played_again_at_the_hit_rate_the_first_dial_favours() -> None:
    learners = (LEARNERS["cmarl-cd"], LEARNERS["vdn"])
    plan = study.ReadingsStudy(learners, rounds=1, hit_rates=(0.6, 0.9), gammas=(0.0, 0.1, 0.9))
    first = plan.first_stage()
    assert [r.name for r in first] == [
        "defaults",
        "tolerance = 1",
        "unseen states: random",
        "hit rate 0.6",
        "hit rate 0.9",
        "γ = 0",
        "γ = 0.1",
    ]
    scores = dict.fromkeys(first, 0.0) | {first[3]: 0.1}  # hit rate 0.6 favoured
    assert [r.name for r in plan.second_stage(scores)] == [
        "γ = 0; hit rate 0.6",
        "γ = 0.1; hit rate 0.6",
    ]
    none = study.ReadingsStudy(learners, rounds=1, hit_rates=(), gammas=(0.0,))
    assert none.second_stage(dict.fromkeys(none.first_stage(), 0.0)) == []


def test_a_study_plays_each_shared_match_once() -> None:
    learners = (LEARNERS["cmarl-cd"], LEARNERS["vdn"])
    plan = study.ReadingsStudy(learners, rounds=2, hit_rates=(0.6, 1.0))
    first = plan.first_stage()
    assert len(first) == 3 + 2 + 5  # switches, hit rates, γ (0.9: the defaults)
    every = [s for r in first for s in plan.tournament(r).specs()]
    unique = plan.specs(first)
    assert len(every) == 10 * 3 * 2
    # VDN against itself is the same match under the 8 readings of the default units
    assert len(unique) == len(every) - 7 * 2
    assert len({s.key for s in unique}) == len(unique)


def test_matches_are_shared_across_the_dials_where_their_keys_agree() -> None:
    learners = (LEARNERS["cmarl-cd"], LEARNERS["vdn"])
    plan = study.ReadingsStudy(learners, rounds=2, hit_rates=(0.9,), gammas=(0.0, 0.9))

    def keys(reading: study.Reading) -> dict:
        return {(s.algorithm, s.run_index): s.key for s in plan.tournament(reading).specs()}

    (hit,) = study.dial((0.9,))
    myopic_hit, plain_hit = study.gamma_dial((0.0, 0.9), hit_rate=0.9)
    assert keys(plain_hit) == keys(hit)  # γ 0.9 at hit rate 0.9 is the hit-rate dial's
    myopic, hit_myopic = keys(study.gamma_dial((0.0,))[0]), keys(myopic_hit)
    for pair in ("cmarl-cd vs cmarl-cd", "cmarl-cd vs vdn"):  # the units differ
        assert all(myopic[(pair, r)] != hit_myopic[(pair, r)] for r in range(2))
    for r in range(2):  # two deep learners: one match under every γ of the same units
        assert hit_myopic[("vdn vs vdn", r)] == keys(hit)[("vdn vs vdn", r)]
        assert myopic[("vdn vs vdn", r)] == keys(study.single_readings()[0])[("vdn vs vdn", r)]


@pytest.mark.parametrize(
    ("gammas", "message"),
    [((-0.1,), r"\[0, 1\)"), ((1.0,), r"\[0, 1\)"), ((), "at least one"), ((0.1, 0.1), "once")],
)
def test_bad_gammas_are_rejected(gammas, message) -> None:
    with pytest.raises(ConfigError, match=message):
        study.ReadingsStudy((LEARNERS["cmarl-cd"],), gammas=gammas)


@pytest.mark.parametrize(
    ("name", "learner_class"), [("cmarl-cd", CMARLCDStochastic), ("la-oca", LAOCA)]
)
def test_each_gamma_of_the_dial_reaches_the_learners_records(name, learner_class) -> None:
    plan = study.ReadingsStudy((LEARNERS[name],), rounds=1, hit_rates=(), gammas=(0.5,))
    (reading,) = [r for r in plan.first_stage() if r.kind == "gamma"]
    (spec,) = plan.tournament(reading).specs()
    config = settings_of(spec).learners[0]  # as the match reads it back from the store
    agent = learner_class([2], config, seed=0)
    for state, reward in ((0, 2.0), (1, 10.0)):  # 2 on the first turn, 10 on the second
        agent.act(state)
        agent.observe(state, (0,), reward)
    agent.end_episode()
    assert agent.max_return(0) == 2.0 + 0.5 * 10.0 and agent.max_return(1) == 10.0


@pytest.mark.parametrize(("rates", "message"), [((0.0,), "hit_rates"), ((1.5,), "hit_rates")])
def test_bad_hit_rates_are_rejected(rates, message) -> None:
    with pytest.raises(ConfigError, match=message):
        study.ReadingsStudy((LEARNERS["cmarl-cd"],), hit_rates=rates)


def test_a_study_too_large_as_a_whole_is_refused_at_once() -> None:
    four = tuple(LEARNERS.values())[:4]  # 10 matches a round
    # 3 switches + 5 hit rates + 5 γ (0.9: the defaults), then 5 γ again (0.9: the
    # favoured hit rate's own tournament) and a combination: 19 tournaments at most
    study.ReadingsStudy(four, rounds=1_052)  # 199,880 runs: within the cap of 200,000
    with pytest.raises(ConfigError, match="rounds"):
        study.ReadingsStudy(four, rounds=1_053)  # each tournament fits, the study does not


def test_a_claim_s_cell_is_its_verdict_and_margins() -> None:
    claim = claim_checks.Claim(
        claim_checks.CLAIMS[0],
        claim_checks.CONTRADICTED,
        "",
        (
            claim_checks.Margin("la-oca", -0.069, 0.041, 10),
            claim_checks.Margin("vdn", -0.23, 0.0515, 10),
        ),
    )
    assert margin_text(claim, 100.0) == "contradicted: LA -6.9±8.2; VDN -23.0±10.3"
    steps = claim_checks.Claim(
        claim_checks.CLAIMS[5],
        claim_checks.SUPPORTED,
        "",
        (claim_checks.Margin("vdn", 0.38, 0.045, 9),),
    )
    assert margin_text(steps, 1.0) == "supported: +0.38±0.09"


# ---------------------------------------------------------------- end to end


@pytest.mark.slow
def test_the_study_runs_resumes_and_is_a_section_of_the_report(tmp_path) -> None:
    where = ["--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "figures")]
    args = ["readings", "--algorithms", "cmarl-cd,la-oca", "--rounds", "2"]
    args += ["--learn-episodes", "200", "--eval-episodes", "200", "--hit-rates", "0.7,1"]
    args += ["--gammas", "0,0.5,0.9", "--workers", "1", "--no-progress", "--json", *where]
    runner = CliRunner()
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    doc = json.loads(done.stdout)
    names = [r["name"] for r in doc["readings"]]
    favoured = max(
        (r for r in doc["readings"] if r["kind"] == "hit rate"),
        key=lambda r: -math.inf if r["main_margin"] is None else r["main_margin"],
    )
    rate = favoured["name"].removeprefix("hit rate ")
    assert names[:7] == [
        "defaults",
        "tolerance = 1",
        "unseen states: random",
        "hit rate 0.7",
        "hit rate 1",
        "γ = 0",
        "γ = 0.5",
    ]
    assert names[7:9] == [f"γ = 0; hit rate {rate}", f"γ = 0.5; hit rate {rate}"]
    assert len(names) in (9, 10)  # and the combination, when the study points to a new one
    assert doc["points_to"]["name"] in names
    assert all(r["rounds"] == 2 and r["matches"] == 6 for r in doc["readings"])
    assert doc["runs_computed"] == 6 * len(names) and doc["runs_reused"] == 0
    assert {"hit_rates", "gamma"} <= set(doc["figures"])
    # the γ dial: each tabular learner against the other, at 3 γ, at 2 unit stats
    dial = doc["gamma_dial"]
    assert len(dial) == 2 * 3 * 2
    assert {(m["gamma"], m["hit_rate"]) for m in dial} == {
        (g, h) for g in (0.0, 0.5, 0.9) for h in (None, float(rate))
    }
    again = json.loads(runner.invoke(app, args).stdout)
    assert again["runs_computed"] == 0 and again["readings"] == doc["readings"]
    # the report draws the dials from the stored matches alone
    for figure in (tmp_path / "figures").iterdir():
        figure.unlink()
    report = json.loads(runner.invoke(app, ["report", "--json", *where]).stdout)
    (section,) = report["readings"]
    assert section["gamma_dial"] == dial and section["points_to"] == doc["points_to"]
    assert all(Path(path).is_file() for path in section["figures"].values())
    assert [r["name"] for r in section["readings"]] == names
    assert len(report["tournament"]) == len(names)
    markdown = runner.invoke(app, ["report", "--format", "markdown", *where]).stdout
    rows = [line for line in markdown.splitlines() if line.startswith("| γ = 0 |")]
    (row,) = rows
    gamma = next(r for r in doc["readings"] if r["name"] == "γ = 0")
    printed = row.split("|")[2].strip()
    if gamma["main_margin"] is None:
        assert printed == "—"
    else:
        assert math.isclose(float(printed), 100 * gamma["main_margin"], abs_tol=0.05)
    # a tournament of another CMARL-CD setting on the same budgets is no reading of the
    # study and shares no cell with its defaults: a tournament of its own, named by it
    other = ["tournament", "--algorithms", "cmarl-cd,la-oca", "--rounds", "2", *args[5:9]]
    other += ["--set", "cmarl-cd.delta=0.08", "--workers", "1", "--no-progress", *where]
    assert runner.invoke(app, other).exit_code == 0
    report = json.loads(runner.invoke(app, ["report", "--json", *where]).stdout)
    (section,) = report["readings"]
    assert all(r["matches"] == 6 for r in section["readings"])
    assert len(report["tournament"]) == len(names) + 1
    (own,) = [t for t in report["tournament"] if "CMARL-CD (delta=0.08)" in t["labels"].values()]
    assert own["rounds"] == 2 and sum(own["versions"].values()) == 6


@pytest.mark.parametrize(
    ("option", "value"),
    [("--hit-rates", "0.5,x"), ("--gammas", "1"), ("--gammas", "-0.1"), ("--gammas", "")],
)
def test_bad_dials_on_the_command_line_are_one_line(tmp_path, option, value) -> None:
    store = tmp_path / "s.sqlite"
    done = CliRunner().invoke(app, ["readings", option, value, "--store", str(store)])
    assert done.exit_code == 2 and option in done.output and not store.exists()
    assert "Traceback" not in done.output


def test_the_tournament_options_of_a_reading_play_that_reading(tmp_path, monkeypatch) -> None:
    """The command the report prints for the reading the study points to plays exactly
    that reading: its options, parsed by ``cmarl-cd tournament``, give its readings."""
    from cmarlcd.cli import tournament as command

    assert study.tournament_options(Readings()) == []
    reading = study.with_hit_rate(Readings(gamma=0.03, tolerance=1.0, unseen="random"), 0.9)
    options = study.tournament_options(reading)
    expected = ["--gamma", "0.03", "--tolerance", "1", "--unseen", "random"]
    expected += ["--marine", "3,1,0.9", "--gunner", "6,2,0.9"]
    assert options == expected
    played = []
    monkeypatch.setattr(command, "print_results", lambda run, work: played.append(run))
    monkeypatch.setattr(command.tour, "Tournament", lambda **kw: played.append(kw["readings"]))
    args = ["tournament", *options, "--store", str(tmp_path / "s.sqlite")]
    done = CliRunner().invoke(app, args)
    assert done.exit_code == 0, done.output
    assert played[0] == reading


def test_a_study_whose_main_claim_was_never_checked_points_nowhere() -> None:
    """Tournaments of the deep learners alone (a study still computing, or one without
    CMARL-CD) check no claim of CMARL-CD: the study favours no hit rate, plays no second
    γ dial and points to no reading, rather than to whichever came first."""
    unchecked = [claim_checks.Claim(claim_checks.CLAIMS[0], claim_checks.NOT_CHECKED, "")]
    learners = (LEARNERS["cmarl-cd"], LEARNERS["vdn"])
    plan = study.ReadingsStudy(learners, rounds=1, hit_rates=(0.6, 0.9), gammas=(0.0,))
    scores = dict.fromkeys(plan.first_stage(), math.nan)
    assert study.favoured_hit_rate(scores) is None and plan.second_stage(scores) == []
    assert study.pointed_to(scores) is None and study.combination(scores) is None
    default, loose, _ = study.single_readings()
    outcomes = [study.Outcome(r, [], [], unchecked) for r in (default, loose)]
    assert _pointed_to(outcomes) is None
    # the defaults unchecked: no switch can be said to help, whatever its margin
    assert study.pointed_to({default: math.nan, loose: -0.1}) is None


def test_without_a_tabular_learner_there_is_no_gamma_dial() -> None:
    plan = study.ReadingsStudy((LEARNERS["vdn"], LEARNERS["qmix"]), rounds=1, hit_rates=(0.9,))
    assert [r.kind for r in plan.first_stage()] == ["default", "single", "single", "hit rate"]
    assert plan.second_stage(dict.fromkeys(plan.first_stage(), 0.1)) == []


def test_the_report_says_when_the_combination_did_worse_than_its_point() -> None:
    def scored(reading: study.Reading, value: float) -> study.Outcome:
        claim = claim_checks.Claim(
            claim_checks.CLAIMS[0], claim_checks.CONTRADICTED, "",
            (claim_checks.Margin("vdn", value, 0.01, 10),),
        )  # fmt: skip
        return study.Outcome(reading, [], [], [claim])

    default, _, unseen = study.single_readings()
    (high,) = study.dial((0.9,))
    combined = study.Reading(study.with_hit_rate(Readings(unseen="random"), 0.9))
    outcomes = [scored(default, -0.2), scored(unseen, -0.1), scored(high, 0.05)]
    pointed = _pointed_to(outcomes)
    assert pointed == combined
    text = _pointed_text(pointed, outcomes)
    assert "unseen states: random; hit rate 0.9 (not played yet)" in text
    assert "best point alone: hit rate 0.9 (mean margin +5.0)" in text
    assert "--unseen random --marine 3,1,0.9 --gunner 6,2,0.9 --rounds 30" in text
    text = _pointed_text(pointed, [*outcomes, scored(combined, 0.01)])
    assert "(mean margin +1.0)" in text and "did worse than its point alone" in text


def test_minus_zero_is_the_same_discount_as_zero() -> None:
    """``--gammas -0`` plays the γ = 0 tournament, sharing its stored matches."""
    (negative,), (zero,) = study.gamma_dial((-0.0,)), study.gamma_dial((0.0,))
    assert negative.name == "γ = 0" and study.tournament_options(negative.readings)[1] == "0"
    learners = (LEARNERS["cmarl-cd"],)
    keys = [
        [s.key for s in study.ReadingsStudy(learners, rounds=1).tournament(r).specs()]
        for r in (negative, zero)
    ]
    assert keys[0] == keys[1]
