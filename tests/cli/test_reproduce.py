"""The ``reproduce`` command end to end on tiny presets: every part of the paper in one
sweep, the paper preset's deep rows, and ``--set`` across its parts."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from tests.cli.common import (
    SECTIONS,
    invoke,
    tiny_paper_preset,
    tiny_reproduction,
    without_torch,
)


@pytest.mark.slow
def test_reproduce_runs_every_table_and_the_theorem(paths, monkeypatch) -> None:
    _, figures, where = paths
    doc = tiny_reproduction(paths, monkeypatch)
    assert [t["case"] for t in doc["repeated"]] == [1, 2]
    assert len(doc["repeated"][0]["cells"]) == 24 and len(doc["repeated"][1]["cells"]) == 12
    assert {r["algorithm"] for r in doc["dsn"]["rows"]} == {"cmarl-cd", "la-oca"}
    assert all(check["confirmed"] for check in doc["theorem1"])
    assert (figures / "theorem1-phase-T1.png").exists()
    players = 4 if importlib.util.find_spec("torch") else 2  # VDN, QMIX need the extra
    assert doc["tournament"]["rounds"] == 1 and len(doc["tournament"]["cells"]) == players**2
    assert Path(doc["tournament"]["figures"]["fig6"]).exists()
    learners = {c["learner"] for c in doc["compare"]["cells"]}
    assert {"cmarl-cd", "iql", "fmq", "jal"} <= learners and Path(doc["compare"]["figure"]).exists()
    bad = invoke("reproduce", "--preset", "huge", *where)
    assert bad.exit_code == 2 and bad.stderr.startswith("error: --preset:")


@pytest.mark.slow
def test_reproduce_paper_preset_has_the_deep_rows(paths, monkeypatch) -> None:
    pytest.importorskip("torch")
    tiny_paper_preset(monkeypatch)
    _, _, where = paths
    result = invoke(
        "reproduce", "--preset", "paper", "--workers", "1", "--no-compare", "--json", *where
    )
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)["dsn"]["rows"]
    assert {r["algorithm"] for r in rows} == {"cmarl-cd", "la-oca", "vdn", "qmix"}


@pytest.mark.slow
def test_reproduce_paper_preset_without_torch_says_what_it_left_out(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    tiny_paper_preset(monkeypatch)
    _, _, where = paths
    result = invoke("reproduce", "--preset", "paper", "--workers", "1", "--no-compare", *where)
    assert result.exit_code == 0, result.output
    assert "note: VDN and QMIX need PyTorch: pip install 'cmarl-cd[deep]'" in result.stderr


@pytest.mark.slow
def test_reproduce_is_one_sweep_with_a_section_per_part_of_the_paper(paths, monkeypatch) -> None:
    from cmarlcd.cli import progress

    seen = {}
    start = progress.RichSweepView.start

    def record(self, sections):
        seen["sections"] = [s.name for s in sections]
        seen["cost"] = sum(s.cost for s in sections)
        start(self, sections)

    monkeypatch.setattr(progress.RichSweepView, "start", record)
    doc = tiny_reproduction(paths, monkeypatch)
    # one bar a unit: the comparison's DSN runs count episodes, its others runs
    assert seen["sections"] == [*SECTIONS, "Comparison: DSN"] and seen["cost"] > 0
    assert doc["runs_computed"] > 0 and doc["runs_reused"] == 0
    times = doc["time"]["time_by_part"]  # the time of each part, this command's runs all
    assert list(times) == list(SECTIONS)
    assert sum(t["runs"] for t in times.values()) == doc["runs_computed"]
    for t in times.values():
        assert t["computed_now"] == t["runs"] and t["compute_seconds"] > 0
        assert 0 < t["done_after_seconds"] <= doc["wall_seconds"] + 1
    again = json.loads(invoke("reproduce", "--workers", "1", "--json", *paths[2]).stdout)
    assert again["runs_computed"] == 0
    for name, t in again["time"]["time_by_part"].items():  # all from the store now
        assert t["computed_now"] == 0 and t["done_after_seconds"] is None
        assert t["compute_seconds"] == times[name]["compute_seconds"]


def test_reproduce_set_goes_to_every_part_its_learner_plays_in() -> None:
    """``reproduce --set``: VDN's step to its DSN rows and its tournament matches,
    CMARL-CD's temperature to its DSN row and every pairing it plays."""
    pytest.importorskip("torch")  # the paper preset's DSN rows include VDN
    from cmarlcd.cli.reproduce import PRESETS, reproduction_plan

    text = "vdn.step=autograd,cmarl-cd.temperature=0.25"
    plan = reproduction_plan(PRESETS["paper"], 0, {}, True, text)
    rows = {s.algorithm: s.config for s in plan["Tables 3-7"]}
    assert "step" not in rows["vdn"]["learner"]  # autograd's, left out of the identity
    assert rows["cmarl-cd"]["learner"]["temperature"] == 0.25
    assert rows["qmix"]["learner"]["step"] == "auto"  # the default
    for spec in plan["Figs. 6-7"]:
        for name, learner in zip(spec.config["algorithms"], spec.config["learners"], strict=True):
            assert (learner.get("step") == "auto") == (name == "qmix")
            assert (learner.get("temperature") == 0.25) == (name == "cmarl-cd")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("jal.alpha=0.1", "error: --set: 'jal' plays in no part of the paper"),
        ("vdn", "error: --set: expected LEARNER.SETTING=VALUE"),
        ("cmarl-cd.temperature=hot", "error: --set:"),
        ("la-oca.nothing=1", "error: --set: la-oca has no setting 'nothing'"),
    ],
)
def test_reproduce_refuses_a_setting_it_cannot_apply(paths, text, message) -> None:
    result = invoke("reproduce", "--preset", "smoke", "--set", text, *paths[2])
    assert result.exit_code == 2 and result.stderr.startswith(message), result.stderr
    assert not paths[0].exists()  # refused before any run
