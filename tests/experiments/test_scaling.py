"""The scaling study: its runs, its rows from stored runs, and its command end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cmarlcd import registry
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import scaling, settings_of
from cmarlcd.games.sensor_network import layout
from cmarlcd.sweeps.store import ResultStore
from tests.cli.common import assert_rejected_cleanly, invoke, without_torch

TABULAR = tuple(registry.require_learner(n) for n in ("cmarl-cd", "iql"))


def test_every_run_stores_its_size_the_papers_included() -> None:
    study = scaling.ScalingStudy(sizes=((2, 3, 2), (2, 2, 1)), learners=TABULAR, runs=3)
    specs = study.specs()
    assert len(specs) == 2 * 2 * 3
    sizes = {scaling.size_of(settings_of(spec).options) for spec in specs}
    assert sizes == {(2, 3, 2), (2, 2, 1)}
    assert len({spec.key for spec in specs}) == len(specs)


def test_a_deep_learner_makes_one_run_per_seed_at_each_size() -> None:
    pytest.importorskip("torch")
    vdn = registry.require_learner("vdn")
    study = scaling.ScalingStudy(sizes=((2, 2, 1), (4, 5, 4)), learners=(vdn,), runs=2)
    assert len(study.specs()) == 4  # one budget: one run per seed, 146,001 states accepted


@pytest.mark.parametrize(
    ("sizes", "parameter"),
    [((), "sizes"), (((2, 2, 1), (2, 2, 1)), "sizes"), (((2, 2, 5),), "sizes")],
)
def test_bad_sizes_are_refused(sizes, parameter) -> None:
    with pytest.raises(ConfigError) as error:
        scaling.ScalingStudy(sizes=sizes, learners=TABULAR)
    assert error.value.parameter == parameter


def test_the_paper_success_is_stored_at_the_papers_size_only() -> None:
    paper = scaling.SCALING_GAME.with_options(scaling.size_options((2, 3, 2)))
    larger = scaling.SCALING_GAME.with_options(scaling.size_options((3, 4, 3)))
    assert [name for name, _ in paper.also] == ["paper_success"]
    assert larger.also == ()
    assert larger.spec.n_states == layout.state_count(12, 3) == 1_753


@pytest.mark.slow
def test_the_study_end_to_end(paths) -> None:
    """Rows from the stored runs: one per size and learner, smallest network first; the
    return per target is the runs' mean return over the targets; a second call computes
    nothing."""
    store, figures, where = paths
    args = (
        "scaling", "--sizes", "2x3/2,2x2/1", "--algorithms", "cmarl-cd,iql",
        "--episodes", "300", "--runs", "2", "--eval-episodes", "100", "--json", *where,
    )  # fmt: skip
    result = invoke(*args)
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert doc["runs_computed"] == 8
    assert [(r["size"], r["algorithm"]) for r in doc["rows"]] == [
        ("2x2/1", "cmarl-cd"),
        ("2x2/1", "iql"),
        ("2x3/2", "cmarl-cd"),
        ("2x3/2", "iql"),
    ]
    with ResultStore(store) as db:
        stored = list(db.records(scaling.EXPERIMENT))
    for row in doc["rows"]:
        size = tuple(int(x) for x in row["size"].replace("/", "x").split("x"))
        runs = [
            r
            for r in stored
            if r.key.algorithm == row["algorithm"]
            and scaling.size_of(settings_of(r).options) == size
        ]
        returns = [r.metrics["checkpoints"]["300"]["mean_return"] for r in runs]
        assert row["return_per_target"] == pytest.approx(np.mean(returns) / size[2])
        assert row["runs"] == 2 and 0.0 <= row["success_rate"] <= 1.0
        assert (row["paper_success"] is not None) == (size == (2, 3, 2))
    assert (figures / doc["figures"]["scaling"].split("/")[-1]).exists()
    again = json.loads(invoke(*args).stdout)
    assert again["runs_computed"] == 0 and again["rows"] == doc["rows"]
    report = invoke("report", "--json", *where)
    assert json.loads(report.stdout)["scaling"][0]["rows"] == doc["rows"]


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--sizes", "3x4"], "--sizes"),
        (["--sizes", "3x4/x"], "--sizes"),
        (["--sizes", "0x4/1"], "--sizes"),
        (["--sizes", "2x2/5"], "--sizes"),
        (["--sizes", "9x9/9"], "--sizes"),  # more than 50M states: refused at once
        (["--sizes", "2x2/1,2x2/1"], "--sizes"),
        (["--preset", "huge"], "--preset"),
        (["--episodes", "0"], "--episodes"),
        (["--runs", "0"], "--runs"),
        (["--algorithms", "nope"], "--algorithms"),
        (["--set", "cmarl-cd.delta=-1"], "--set"),
    ],
)
def test_bad_input_is_one_line(paths, args, option) -> None:
    store, figures, where = paths
    result = invoke("scaling", "--sizes", "2x2/1", "--episodes", "10", *where, *args)
    assert_rejected_cleanly(result, option, store, figures)


@pytest.mark.slow
def test_without_torch_the_deep_learners_are_left_out_with_a_note(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    _, _, where = paths
    args = ("--sizes", "2x2/1", "--episodes", "50", "--runs", "1", "--eval-episodes", "20")
    result = invoke("scaling", *args, "--json", *where)
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert {r["algorithm"] for r in doc["rows"]} == {"cmarl-cd", "distributed-q"}
    assert "cmarl-cd[deep]" in doc["skipped"]
    refused = invoke("scaling", *args, "--algorithms", "vdn", *where)
    assert refused.exit_code == 2 and "cmarl-cd[deep]" in refused.stderr
