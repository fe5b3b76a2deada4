"""The DSN protocol (Section V-A): runs, checkpoints, Tables 3-7 aggregation."""

from __future__ import annotations

import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.experiments import episodic, episodic_results, settings_of
from cmarlcd.experiments import sensor_network as sn
from cmarlcd.learners import AutomatonConfig, DeepConfig, StochasticConfig
from cmarlcd.progress import progress_sink
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore, RunKey, RunRecord, canonical_json


def run(sweep: sn.DsnSweep, algorithm: str = "cmarl-cd", index: int = 0) -> dict:
    spec = next(s for s in sweep.specs() if s.algorithm == algorithm and s.run_index == index)
    return episodic.run(sn.DSN_GAME, settings_of(spec), spec.seed_sequence())


def test_paper_protocol_specs() -> None:
    sweep = sn.DsnSweep()
    assert len(sweep.specs()) == 2 * 50
    assert sweep.algorithms == ("cmarl-cd", "la-oca")
    assert sweep.settings(StochasticConfig()).checkpoints == (100_000, 300_000, 500_000)
    assert sweep.settings(AutomatonConfig()).eval_episodes == 50_000
    deep = sn.DsnSweep(learners=(DeepConfig(mixer="qmix"),))
    assert [s.config["checkpoints"] for s in deep.specs()[::50]] == [
        [100_000],
        [300_000],
        [500_000],
    ]


@pytest.mark.slow
@pytest.mark.parametrize("learner", [StochasticConfig(), DeepConfig(batch_size=20, train_every=10)])
def test_a_run_reports_exactly_its_work(learner) -> None:
    """The progress bar's total is the episodes every run reports, learning and evaluation,
    and the estimated seconds it reports with them add up to its estimated cost."""
    sweep = sn.DsnSweep(
        learners=(learner,), episodes=(30, 60), eval_episodes=40, curve_points=4, runs=1
    )
    reported: list[tuple[float, float]] = []
    for spec in sweep.specs():
        with progress_sink(lambda amount, seconds: reported.append((amount, seconds))):
            episodic.run(sn.DSN_GAME, settings_of(spec), spec.seed_sequence())
    units, seconds = (sum(column) for column in zip(*reported, strict=True))
    assert units == sum(settings_of(s).work() for s in sweep.specs())
    expected = sum(sn.DSN.cost(settings_of(s)) for s in sweep.specs())
    assert seconds == pytest.approx(expected, rel=1e-9)


def test_a_checkpoint_does_not_depend_on_the_other_checkpoints() -> None:
    """Training streams are seeded by the learner only; evaluation streams by L."""
    both = run(sn.DsnSweep(episodes=(400, 900), eval_episodes=300, curve_points=3, runs=1))
    alone = run(sn.DsnSweep(episodes=(400,), eval_episodes=300, curve_points=0, runs=1))
    assert both["checkpoints"]["400"] == alone["checkpoints"]["400"]
    assert [c[0] for c in both["curve"]] == [300, 400, 600, 900]


def test_run_metrics_are_deterministic_and_well_formed() -> None:
    sweep = sn.DsnSweep(episodes=(500,), eval_episodes=200, curve_points=2, runs=2)
    first, again, other = run(sweep), run(sweep), run(sweep, index=1)
    first.pop("seconds"), again.pop("seconds"), other.pop("seconds")
    assert first == again and first != other
    result = first["checkpoints"]["500"]
    assert 0.0 <= result["success_rate"] <= 1.0 and 1.0 <= result["mean_steps"] <= 40.0
    assert len(first["policy"]) == 42 and len(first["policy"][0]) == 12


def record(algorithm: str, index: int, checkpoints: dict, learner=None) -> RunRecord:
    from cmarlcd.registry import LEARNERS

    settings = sn.DsnSweep().settings(learner or LEARNERS[algorithm])
    key = RunKey("dsn", algorithm, canonical_json(settings.to_config()), 0, index)
    return RunRecord(key, {"checkpoints": checkpoints, "curve": [], "policy": []}, 1.0)


def test_tables_3_to_7_aggregate_as_the_paper_defines_them() -> None:
    runs = [
        {"100000": {"success_rate": 1.0, "mean_return": 42.0, "mean_steps": 3.0}},
        {"100000": {"success_rate": 0.5, "mean_return": 40.0, "mean_steps": 4.0}},
    ]
    (row,) = episodic_results.summarize(
        sn.DSN_GAME, (record("cmarl-cd", i, c) for i, c in enumerate(runs))
    )
    assert (row.algorithm, row.episodes, row.runs) == ("cmarl-cd", 100_000, 2)
    assert row.success_rate == 0.75  # Table 3: mean of the per-run success rates
    assert (row.mean_return, row.std_return) == (41.0, 1.0)  # Table 4 (population std)
    assert (row.mean_steps, row.std_steps) == (3.5, 0.5)  # Table 5
    assert (row.min_return, row.max_steps) == (40.0, 4.0)  # Tables 6 and 7
    assert row.paper["success_rate"] == pytest.approx(0.909) and row.label == "CMARL-CD"


def test_non_default_settings_are_named_and_have_no_paper_values() -> None:
    changed = StochasticConfig(delta=0.1, temperature=2.0)
    assert episodic_results.row_label(changed) == "CMARL-CD (delta=0.1, temperature=2.0)"
    result = {"100000": {"success_rate": 1.0, "mean_return": 42.0, "mean_steps": 3.0}}
    (row,) = episodic_results.summarize(sn.DSN_GAME, [record("cmarl-cd", 0, result, changed)])
    assert row.label == "CMARL-CD (delta=0.1, temperature=2.0)"
    assert set(row.paper.values()) == {None}


def test_two_settings_of_one_learner_are_two_rows_of_their_own_runs() -> None:
    """Runs 0 and 1 of delta=0.02 and of delta=0.08 (the same run indices, as two sweeps
    on one store make them): two rows of two runs each, never one row of two runs."""
    results = {0.02: (1.0, 40.0), 0.08: (0.0, 20.0)}
    records = [
        record(
            "cmarl-cd",
            i,
            {"100000": {"success_rate": rate, "mean_return": ret, "mean_steps": 3.0}},
            StochasticConfig(delta=delta),
        )
        for delta, (rate, ret) in results.items()
        for i in range(2)
    ]
    rows = episodic_results.summarize(sn.DSN_GAME, records)
    found = {r.label: (r.runs, r.success_rate, r.mean_return) for r in rows}
    assert found == {
        "CMARL-CD (delta=0.02)": (2, 1.0, 40.0),
        "CMARL-CD (delta=0.08)": (2, 0.0, 20.0),
    }


@pytest.mark.slow
def test_small_sweep_through_the_runner(tmp_path) -> None:
    sweep = sn.DsnSweep(episodes=(200, 400), eval_episodes=100, curve_points=2, runs=2)
    with ResultStore(tmp_path / "s.sqlite") as store:
        run_sweep(sweep.specs(), store, workers=1)
        records = store.get(s.key for s in sweep.specs())
    rows = episodic_results.summarize(sn.DSN_GAME, records)
    assert [(r.label, r.episodes, r.runs) for r in rows] == [
        ("CMARL-CD", 200, 2),
        ("CMARL-CD", 400, 2),
        ("LA-OCA", 200, 2),
        ("LA-OCA", 400, 2),
    ]
    curves = episodic_results.learning_curves(records)
    assert curves["CMARL-CD"].shape == (2, 2, 4)


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"learners": (StochasticConfig(), StochasticConfig(delta=0.1))}, "algorithms"),
        ({"learners": ()}, "algorithms"),
        ({"episodes": (0, 100)}, "episodes"),
        ({"runs": 0}, "runs"),
        ({"eval_episodes": 0}, "eval_episodes"),
    ],
)
def test_bad_sweeps_are_rejected(kwargs: dict, parameter: str) -> None:
    with pytest.raises(ConfigError) as info:
        sn.DsnSweep(**kwargs)
    assert info.value.parameter == parameter
