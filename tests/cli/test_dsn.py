"""The ``dsn`` command end to end on tiny budgets: tables, figures, resume, the deep
baselines, ``--set``, and bad input."""

from __future__ import annotations

import json

import pytest

from tests.cli.common import (
    assert_rejected_cleanly,
    invoke,
    without_torch,
)


@pytest.mark.slow
def test_dsn_json_tables_figures_and_resume(paths) -> None:
    _, figures, where = paths
    args = [
        "dsn",
        "--episodes",
        "200,400",
        "--runs",
        "2",
        "--eval-episodes",
        "100",
        "--workers",
        "1",
        "--json",
        *where,
    ]
    first = invoke(*args)
    assert first.exit_code == 0, first.output
    doc = json.loads(first.stdout)
    rows = {(r["algorithm"], r["episodes"]): r for r in doc["rows"]}
    assert set(rows) == {(a, e) for a in ("cmarl-cd", "la-oca") for e in (200, 400)}
    keys = {
        "success_rate",
        "mean_return",
        "std_return",
        "mean_steps",
        "std_steps",
        "min_return",
        "max_steps",
    }
    assert all(keys <= set(r) and r["runs"] == 2 for r in rows.values())
    assert "trains once" in doc["note"]
    for path in doc["figures"].values():
        assert (figures / path.split("/")[-1]).stat().st_size > 10_000
    again = json.loads(invoke(*args).stdout)
    assert again["runs_computed"] == 0 and again["rows"] == doc["rows"]
    text = invoke("report", *where)
    assert text.exit_code == 0 and "Table 3" in text.stdout and "Table 1" not in text.stdout


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--algorithms", "cmarl-cd,dqn"], "--algorithms"),
        (["--episodes", "0"], "--episodes"),
        (["--episodes", "-5"], "--episodes"),
        (["--episodes", "many"], "--episodes"),
        (["--runs", "0"], "--runs"),
        (["--eval-episodes", "0"], "--eval-episodes"),
        (["--c-min", "2", "--c-max", "1"], "--c-max"),
        (["--gamma", "-0.1"], "--gamma"),
        (["--gamma", "1.01"], "--gamma"),
        (["--rate", "1"], "--rate"),
        (["--set", "cmarl-cd.delta=x"], "--set"),
        (["--set", "cmarl-cd.nope=1"], "--set"),
        (["--set", "vdn.lr=0.1"], "--set"),  # VDN does not play
        (["--set", "delta=0.1"], "--set"),
        (["--set", "cmarl-cd.delta=-1"], "--set"),
        (["--grid", "3"], "--grid"),
        (["--grid", "0x4"], "--grid"),
        (["--targets", "0"], "--targets"),
        (["--grid", "3x4", "--targets", "13"], "--targets"),
        (["--grid", "20x20", "--targets", "4"], "--targets"),  # 2.5e10 states
        (["--grid", "1000x1000", "--targets", "100000"], "--targets"),  # refused at once
        (["--grid", "6x6", "--targets", "4"], "--targets"),  # a 78M-entry policy table
        (["--algorithms", "vdn", "--set", "vdn.mixer=qmix"], "--set"),  # another learner
    ],
)
def test_dsn_bad_input(paths, args, option) -> None:
    store, figures, where = paths
    result = invoke("dsn", "--episodes", "10", "--runs", "1", *where, *args)
    assert result.exit_code == 2
    assert_rejected_cleanly(result, option, store, figures)


@pytest.mark.slow
def test_a_larger_sensor_network_end_to_end(paths) -> None:
    """``--grid``/``--targets``: its own rows (no paper values, success = every target
    captured), stored with the layout; the paper's grid keeps its keys."""
    import json

    torch = pytest.importorskip("torch")  # noqa: F841  (VDN reads the same layout)
    store, _, where = paths
    args = ("--episodes", "300", "--runs", "1", "--eval-episodes", "50", "--json")
    result = invoke(
        "dsn", "--grid", "2x2", "--targets", "1", "--algorithms", "cmarl-cd,vdn", *args, *where
    )
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert "grid 2x2, targets 1" in doc["title"]
    assert {r["label"] for r in doc["rows"]} == {
        "CMARL-CD, grid 2x2, targets 1",
        "VDN, grid 2x2, targets 1",
    }
    assert all(set(r["paper"].values()) == {None} for r in doc["rows"])
    assert all(0.0 <= r["success_rate"] <= 1.0 for r in doc["rows"])
    from cmarlcd.experiments import settings_of
    from cmarlcd.sweeps.store import ResultStore

    with ResultStore(store) as db:
        layouts = {settings_of(r).options for r in db.records("dsn")}
    assert layouts == {(("grid", (2, 2)), ("targets", 1))}


def test_set_reaches_the_learner_s_stored_settings(paths) -> None:
    """``--set`` changes a learner's setting: the run is stored with it (a new key)."""
    store, _, where = paths
    args = ("--algorithms", "cmarl-cd", "--episodes", "20", "--runs", "1", "--eval-episodes", "5")
    assert invoke("dsn", *args, *where, "--set", "cmarl-cd.delta=0.1").exit_code == 0
    from cmarlcd.experiments import settings_of
    from cmarlcd.sweeps.store import ResultStore

    with ResultStore(store) as db:
        (record,) = db.records("dsn")
    assert settings_of(record).learner.delta == 0.1


@pytest.mark.slow
def test_dsn_deep_baselines_from_the_cli(paths) -> None:
    pytest.importorskip("torch")
    _, _, where = paths
    args = [
        "dsn",
        "--algorithms",
        "vdn,qmix",
        "--episodes",
        "20,40",
        "--runs",
        "2",
        "--eval-episodes",
        "50",
        "--workers",
        "1",
        "--json",
        *where,
    ]
    result = invoke(*args)
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert {(r["algorithm"], r["episodes"], r["runs"]) for r in doc["rows"]} == {
        (a, e, 2) for a in ("vdn", "qmix") for e in (20, 40)
    }
    assert doc["runs_computed"] == 8 and "a run of its own" in doc["note"]


def test_dsn_deep_without_torch_names_the_extra(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    store, _, where = paths
    result = invoke("dsn", "--algorithms", "cmarl-cd,qmix", "--episodes", "10", *where)
    assert result.exit_code == 2 and "cmarl-cd[deep]" in result.stderr
    assert not store.exists()


@pytest.mark.slow
def test_dsn_tables_state_their_runs_and_mark_other_settings(paths) -> None:
    _, _, where = paths
    base = ["dsn", "--algorithms", "cmarl-cd", "--episodes", "50", "--runs", "2", "--workers", "1"]
    paper = invoke(*base, "--eval-episodes", "1k", "--no-progress", *where)
    assert paper.exit_code == 0, paper.output
    assert "2 runs per cell, 1,000 evaluation episodes" in paper.stdout
    other = invoke(*base, "--eval-episodes", "20", "--delta", "0.1", "--json", *where)
    (row,) = json.loads(other.stdout)["rows"]
    assert row["label"] == "CMARL-CD (delta=0.1)" and set(row["paper"].values()) == {None}
