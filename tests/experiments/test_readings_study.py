"""The battlefield readings study: which tournaments it plays, the combination the single
changes point to, its table read back from the store, and the command end to end."""

from __future__ import annotations

import json
import math

import pytest
from typer.testing import CliRunner

from cmarlcd.cli import app
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import readings as study
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments.tournament import Readings, Unit
from cmarlcd.reports.readings import margin_text

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
    assert [r.name for r in singles[1:]] == ["γ = 0", "tolerance = 1", "unseen states: random"]
    for rate, reading in zip(study.HIT_RATES, study.dial(), strict=True):
        units = (reading.readings.marine, reading.readings.gunner)
        assert units == (Unit(3, 1, rate), Unit(6, 2, rate)) and reading.kind == "hit rate"
        assert reading.name == f"hit rate {rate:g}"
    assert study.Reading(Readings(marine=Unit(3, 1, 0.7))).kind == "single"  # one kind only


def named(*readings: Readings) -> list[study.Reading]:
    return [study.Reading(r) for r in readings]


def test_the_combination_takes_every_change_that_raises_cmarl_cd_s_margin() -> None:
    default, gamma, loose, unseen = study.single_readings()
    low, high = study.dial((0.6, 1.0))
    scores = {default: -0.20, gamma: -0.10, unseen: -0.25, loose: -0.19, low: -0.15, high: 0.1}
    combined = study.combination(scores)
    # γ = 0 and the loose tolerance raise it; the best hit rate of the dial too (1.0)
    assert combined.readings == study.with_hit_rate(Readings(gamma=0.0, tolerance=1.0), 1.0)
    assert combined.kind == "combined" and combined.name == "γ = 0; tolerance = 1; hit rate 1"
    only_one = {default: 0.0, gamma: -0.1, unseen: 0.05, loose: -0.2, low: -0.1, high: -0.3}
    assert study.combination(only_one) is None  # that tournament is already played


def test_a_study_plays_each_shared_match_once() -> None:
    learners = (LEARNERS["cmarl-cd"], LEARNERS["vdn"])
    plan = study.ReadingsStudy(learners, rounds=2, hit_rates=(0.6, 1.0))
    first = plan.first_stage()
    assert len(first) == 4 + 2
    every = [s for r in first for s in plan.tournament(r).specs()]
    unique = plan.specs(first)
    assert len(every) == 6 * 3 * 2
    # VDN against itself is the same match under the four readings of the tabular side
    assert len(unique) == len(every) - 3 * 2
    assert len({s.key for s in unique}) == len(unique)


@pytest.mark.parametrize(("rates", "message"), [((0.0,), "hit_rates"), ((1.5,), "hit_rates")])
def test_bad_hit_rates_are_rejected(rates, message) -> None:
    with pytest.raises(ConfigError, match=message):
        study.ReadingsStudy((LEARNERS["cmarl-cd"],), hit_rates=rates)


def test_a_study_too_large_as_a_whole_is_refused_at_once() -> None:
    four = tuple(LEARNERS.values())  # 10 matches a round, 4 + 5 + 1 tournaments
    study.ReadingsStudy(four, rounds=1_000)  # 100,000 runs: within the cap
    with pytest.raises(ConfigError, match="rounds"):
        study.ReadingsStudy(four, rounds=5_000)  # each tournament fits, the study does not


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
    args += ["--workers", "1", "--no-progress", "--json", *where]
    runner = CliRunner()
    done = runner.invoke(app, args)
    assert done.exit_code == 0, done.output
    doc = json.loads(done.stdout)
    names = [r["name"] for r in doc["readings"]]
    assert names[:6] == [
        "defaults",
        "γ = 0",
        "tolerance = 1",
        "unseen states: random",
        "hit rate 0.7",
        "hit rate 1",
    ]
    assert all(r["rounds"] == 2 and r["matches"] == 6 for r in doc["readings"])
    assert doc["runs_computed"] == 6 * len(names) and doc["runs_reused"] == 0
    assert (tmp_path / "figures").is_dir() and "hit_rates" in doc["figures"]
    again = json.loads(runner.invoke(app, args).stdout)
    assert again["runs_computed"] == 0 and again["readings"] == doc["readings"]
    markdown = runner.invoke(app, ["report", "--format", "markdown", *where]).stdout
    rows = [line for line in markdown.splitlines() if line.startswith("| γ = 0 |")]
    (row,) = rows
    gamma = next(r for r in doc["readings"] if r["name"] == "γ = 0")
    printed = row.split("|")[2].strip()
    if gamma["main_margin"] is None:
        assert printed == "—"
    else:
        assert math.isclose(float(printed), 100 * gamma["main_margin"], abs_tol=0.05)
    report = json.loads(runner.invoke(app, ["report", "--json", *where]).stdout)
    (section,) = report["readings"]
    assert [r["name"] for r in section["readings"]] == names
    assert len(report["tournament"]) == len(names)
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


def test_bad_hit_rates_on_the_command_line_are_one_line(tmp_path) -> None:
    store = tmp_path / "s.sqlite"
    done = CliRunner().invoke(app, ["readings", "--hit-rates", "0.5,x", "--store", str(store)])
    assert done.exit_code == 2 and "--hit-rates" in done.output and not store.exists()
