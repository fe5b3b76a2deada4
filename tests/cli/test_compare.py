"""The ``compare`` command end to end on tiny budgets, and the fused step from the
command line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.common import (
    assert_rejected_cleanly,
    invoke,
    without_torch,
)


def test_compare_deep_without_torch_names_the_extra(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    store, _, where = paths
    result = invoke("compare", "--learners", "deep-cmarl-cd", "--games", "climbing", *where)
    assert result.exit_code == 2 and "cmarl-cd[deep]" in result.stderr
    assert not store.exists()


def test_compare_end_to_end_json_then_resume(paths) -> None:
    where = paths[2]
    args = ["compare", "--learners", "cmarl-cd,fmq", "--games", "climbing,climbing-ps"]
    first = invoke(*args, "--runs", "3", "--json", "--no-progress", *where)
    assert first.exit_code == 0, first.stderr
    doc = json.loads(first.stdout)
    cells = {(c["learner"], c["game"]): c for c in doc["cells"]}
    assert set(cells) == {(a, g) for a in ("cmarl-cd", "fmq") for g in ("climbing", "climbing-ps")}
    for cell in cells.values():
        assert cell["runs"] == 3 and 0.0 <= cell["optimal_rate"] <= 1.0
        assert cell["median_games"] >= 0
    assert doc["runs_computed"] == 12 and Path(doc["figure"]).is_file()
    again = invoke(*args, "--runs", "3", "--no-progress", *where)
    assert again.exit_code == 0 and "0 runs computed, 12 from the store" in again.stdout
    assert "% of runs ending on an optimal joint action" in again.stdout


def test_compare_set_changes_a_learners_settings(paths) -> None:
    """``--set`` gives the learner other settings: its runs are new ones (not the
    default's, already stored), labelled with the change."""
    where = paths[2]
    args = ["compare", "--learners", "cmarl-cd", "--games", "climbing", "--runs", "2"]
    assert invoke(*args, "--no-progress", *where).exit_code == 0
    changed = invoke(*args, "--set", "cmarl-cd.delta=0.2", "--json", "--no-progress", *where)
    assert changed.exit_code == 0, changed.stderr
    doc = json.loads(changed.stdout)
    assert doc["runs_computed"] == 2 and doc["runs_reused"] == 0
    assert "delta=0.2" in json.dumps(doc["cells"])


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--learners", "sarsa"], "--learners"),
        (["--games", "chess"], "--games"),
        (["--runs", "0"], "--runs"),
        (["--learners", ""], "--learners"),
        (["--set", "cmarl-cd.nonsense=1"], "--set"),
        (["--set", "cmarl-cd.delta=-1"], "--set"),
    ],
)
def test_compare_rejects_bad_input(paths, args, option) -> None:
    store, figures, where = paths
    result = invoke("compare", *args, *where)
    assert_rejected_cleanly(result, option, store, figures)


@pytest.mark.parametrize(
    "command",
    [
        pytest.param(
            ["dsn", "--algorithms", "vdn,deep-cmarl-cd", "--episodes", "100", "--runs", "1",
             "--eval-episodes", "20", "--set", "vdn.step=fused,deep-cmarl-cd.step=fused"],
            id="dsn", marks=pytest.mark.slow,
        ),
        pytest.param(
            ["tournament", "--algorithms", "vdn,qmix", "--rounds", "1", "--learn-episodes",
             "40", "--eval-episodes", "10", "--set", "vdn.step=fused,qmix.step=fused"],
            id="tournament", marks=pytest.mark.slow,
        ),
    ],
)  # fmt: skip
def test_the_fused_step_from_the_command_line(tmp_path, command: list[str]) -> None:
    """The deep learners with ``step=fused`` named (the DSN's one-hot states; the
    battlefield's features), as a user runs them: exit 0; the same seeds give the same
    stored numbers twice; the runs are others than autograd's (the setting is in their
    identity). Slow: the default run takes the fused step from the command line in
    ``train``'s fixed-seed runs at ``step=auto`` (tests/experiments/test_environment.py)."""
    pytest.importorskip("torch")
    from tests.helpers import stored

    def run(name: str, args: list[str]) -> dict:
        store = tmp_path / f"{name}.sqlite"
        args = [*args, "--workers", "1", "--no-progress", "--store", str(store)]
        args += ["--figures", str(tmp_path / "figures")]
        done = subprocess.run(
            [sys.executable, "-m", "cmarlcd", *args], capture_output=True, text=True, timeout=900
        )
        assert done.returncode == 0, done.stderr[-3000:]
        return stored(store)

    first, second = run("first", command), run("second", command)
    assert first and first == second
    autograd = [*command[:-1], command[-1].replace("=fused", "=autograd")]
    assert not set(first) & set(run("autograd", autograd))
