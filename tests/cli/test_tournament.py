"""The ``tournament`` command end to end on tiny budgets."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.cli.common import (
    assert_rejected_cleanly,
    invoke,
    without_torch,
)


def test_tournament_json_figures_resume_and_report(paths) -> None:
    _, _, where = paths
    args = ["tournament", "--rounds", "2", "--learn-episodes", "30", "--eval-episodes", "40"]
    args += ["--algorithms", "cmarl-cd,la-oca"]
    result = invoke(*args, "--workers", "1", "--json", *where)
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["runs_computed"] == 2 * 3 and doc["rounds"] == 2
    cells = {(c["algorithm"], c["opponent"]): c for c in doc["cells"]}
    assert set(cells) == {(a, b) for a in ("cmarl-cd", "la-oca") for b in ("cmarl-cd", "la-oca")}
    for cell in cells.values():
        total = cell["win_rate"] + cell["loss_rate"] + cell["tie_rate"]
        assert total == pytest.approx(1.0) and cell["rounds"] == 2
    assert cells[("cmarl-cd", "la-oca")]["win_rate"] == pytest.approx(
        cells[("la-oca", "cmarl-cd")]["loss_rate"]
    )
    assert {c["verdict"] for c in doc["claims"]} <= {
        "supported",
        "not separated",
        "contradicted",
        "not checked",
    }
    assert all(Path(path).exists() for path in doc["figures"].values())
    again = json.loads(invoke(*args, "--json", *where).stdout)
    assert again["runs_computed"] == 0 and again["runs_reused"] == 6
    assert again["cells"] == doc["cells"]
    text = invoke("report", *where)
    assert text.exit_code == 0 and "Fig. 6" in text.stdout and "Fig. 7" in text.stdout
    assert "CMARL-CD needs the fewest win steps" in text.stdout


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--algorithms", "foo"], "--algorithms"),
        (["--algorithms", "cmarl-cd,iql"], "--algorithms"),  # no battlefield settings
        (["--rounds", "0"], "--rounds"),
        (["--learn-episodes", "0"], "--learn-episodes"),
        (["--eval-episodes", "-3"], "--eval-episodes"),
        (["--learn-episodes", "many"], "--learn-episodes"),
        (["--gamma", "-0.5"], "--gamma"),
        (["--gamma", "2"], "--gamma"),
        (["--tolerance", "-1"], "--tolerance"),
        (["--unseen", "highest"], "--unseen"),
        (["--marine", "3,1"], "--marine"),
        (["--marine", "0,1,0.8"], "--marine"),
        (["--marine", "3,1.5,0.8"], "--marine"),
        (["--gunner", "6,2,0"], "--gunner"),
        (["--gunner", "6,2,1.2"], "--gunner"),
        (["--gunner", "6,0,0.6"], "--gunner"),
        (["--gunner", "99,2,0.6", "--marine", "99,1,0.8"], "--marine"),
        (["--gunner", "99,2,0.6"], "--gunner"),
        (["--marine", "3,99999999999999999999,0.8"], "--marine"),
        (["--tolerance", "nan"], "--tolerance"),
    ],
)
def test_tournament_bad_input(paths, args, option) -> None:
    store, figures, where = paths
    result = invoke("tournament", "--rounds", "1", *where, *args)
    assert_rejected_cleanly(result, option, store, figures)


def test_tournament_readings_are_recorded_shown_and_kept_apart(paths) -> None:
    _, _, where = paths
    args = ["tournament", "--algorithms", "cmarl-cd", "--rounds", "1", "--learn-episodes", "30"]
    args += ["--eval-episodes", "30", "--workers", "1", "--json", *where]
    default = json.loads(invoke(*args).stdout)
    changed = ["--gamma", "0", "--unseen", "random", "--gunner", "6,2,0.9"]
    doc = json.loads(invoke(*args, *changed).stdout)
    assert doc["runs_computed"] == 1 and doc["runs_reused"] == 0  # a match of its own
    assert doc["readings"]["gamma"] == 0 and doc["readings"]["unseen"] == "random"
    assert doc["readings"]["gunner"] == {"hp": 6, "damage": 2, "hit_rate": 0.9}
    assert "γ = 0; unseen states: random; gunner hit rate 0.9" in doc["settings"]
    assert default["readings"]["gamma"] == 0.9 and "readings: defaults" in default["settings"]
    report = json.loads(invoke("report", "--json", *where).stdout)
    assert sorted(t["title"] for t in report["tournament"]) == [
        "Figs. 6-7: the blood battlefield tournament",
        "Figs. 6-7: the blood battlefield tournament (γ = 0; unseen states: random; gunner "
        "hit rate 0.9)",
    ]


@pytest.mark.slow
def test_tournament_with_every_algorithm(paths) -> None:
    pytest.importorskip("torch")
    _, _, where = paths
    args = ["tournament", "--rounds", "1", "--learn-episodes", "20", "--eval-episodes", "20"]
    result = invoke(*args, "--workers", "1", "--json", *where)
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["runs_computed"] == 10
    names = ("cmarl-cd", "la-oca", "vdn", "qmix")
    assert {(c["algorithm"], c["opponent"]) for c in doc["cells"]} == {
        (a, b) for a in names for b in names
    }
    assert all(c["verdict"] != "not checked" for c in doc["claims"])


def test_tournament_deep_without_torch_names_the_extra(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    store, figures, where = paths
    result = invoke("tournament", "--rounds", "1", *where)
    assert_rejected_cleanly(result, "--algorithms", store, figures)
    assert "pip install 'cmarl-cd[deep]'" in result.stderr
