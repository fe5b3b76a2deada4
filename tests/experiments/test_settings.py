"""Typed settings: every run the package plans reads back from its stored config as the
same settings, so the store's keys, the random streams and old stores stay as they are."""

from __future__ import annotations

from cmarlcd.cli.reproduce import PRESETS, comparison_of, reproduction_plan
from cmarlcd.experiments import readings, settings_of, theorem
from cmarlcd.experiments import sensor_network as sn
from cmarlcd.experiments import tournament as tour
from cmarlcd.games.battlefield import Unit
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.store import canonical_json


def planned_specs() -> list[RunSpec]:
    """The quick preset's runs, its comparison, a readings study and a Theorem 1 check."""
    specs = [s for part in reproduction_plan(PRESETS["quick"], 0, {}, True).values() for s in part]
    specs += comparison_of(PRESETS["quick"], 3).specs()
    study = readings.ReadingsStudy(tuple(tour.battlefield_learners().values()), rounds=1)
    specs += study.specs(study.first_stage())
    larger = sn.DsnSweep(
        episodes=(50,), runs=1, eval_episodes=5, options=sn.layout_options(3, 4, 3)
    )
    specs += larger.specs()
    return specs + theorem.specs(((3, 2),), 0.5, 7, seed=5)


def test_every_planned_run_reads_back_as_the_settings_it_was_made_from() -> None:
    specs = planned_specs()
    assert {s.experiment for s in specs} == {"repeated", "dsn", "tournament", "theorem1", "compare"}
    for spec in specs:
        settings = settings_of(spec)
        assert canonical_json(settings.to_config()) == spec.config_json
        again = RunSpec.make(spec.experiment, spec.algorithm, settings, spec.root_seed, 0)
        assert again.stream_json == spec.stream_json  # the same random streams


def test_a_tournament_records_only_the_readings_that_apply() -> None:
    """The unit stats are stored when they differ from the paper's; what a tabular side
    plays in unseen states only for a pairing with a tabular side."""
    learners = tour.battlefield_learners()
    marine = Unit(4, 2, 1.0)
    readings_ = tour.Readings(unseen="random", marine=marine)
    contest = tour.Tournament((learners["cmarl-cd"], learners["vdn"]), rounds=1, readings=readings_)
    by_name = {s.algorithm: s for s in contest.specs()}
    tabular, deep = by_name["cmarl-cd vs vdn"], by_name["vdn vs vdn"]
    assert tabular.config["unseen"] == "random" and "unseen" not in deep.config
    assert settings_of(tabular).unseen == "random" and settings_of(deep).unseen == "lowest"
    assert settings_of(deep).marine == marine and settings_of(deep).rules.marine == marine
    assert "unseen" not in settings_of(tabular).stream()  # it changes the evaluation alone
