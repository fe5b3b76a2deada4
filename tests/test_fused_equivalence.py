"""The equivalence study of the fused step (benchmarks/fused_equivalence.py): both sides
computed into one store and tested cell by cell, and bad input refused."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parents[1] / "benchmarks/fused_equivalence.py"


def study(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, check=False
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["tournament", "--algorithms", "deep-cmarl-cd"], "tournament compares vdn, qmix"),
        (["dsn", "--algorithms", "iql"], "dsn compares vdn, qmix, deep-cmarl-cd (got iql)"),
        (["dsn", "--runs", "1"], "--runs: at least 2 runs a side"),
        (["dsn", "--runs", "5", "--first-run", "5"], "--first-run: from 0 to --runs - 1"),
        (["dsn", "--report-only", "--out", "/nonexistent/x"], "no study stored at"),
        (["field", "--algorithms", "vdn"], "field compares deep-cmarl-cd (got vdn)"),
    ],
)
def test_bad_input_is_refused(args: list[str], message: str) -> None:
    done = study(*args)
    assert done.returncode == 2 and message in done.stderr.splitlines()[-1]


@pytest.mark.slow
def test_a_tiny_study_tests_every_cell_of_both_steps(tmp_path: Path) -> None:
    done = study(
        "dsn", "--runs", "3", "--episodes", "300", "--eval-episodes", "20", "--workers", "1",
        "--out", str(tmp_path), "--markdown",
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "| dsn vdn L=300 | success rate |" in done.stdout
    result = json.loads((tmp_path / "dsn.json").read_text())
    cells = {(cell["cell"], cell["metric"]) for cell in result["cells"]}
    assert cells == {
        (f"{name} L=300", metric)
        for name in ("vdn", "qmix")
        for metric in ("success_rate", "mean_steps")
    }
    for cell in result["cells"]:
        assert cell["reference_runs"] == cell["candidate_runs"] == 3


@pytest.mark.slow
def test_a_tiny_tournament_study_tests_every_pairing(tmp_path: Path) -> None:
    done = study(
        "tournament", "--runs", "2", "--learn-episodes", "150", "--eval-episodes", "20",
        "--workers", "1", "--out", str(tmp_path),
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    result = json.loads((tmp_path / "tournament.json").read_text())
    pairings = {cell["cell"] for cell in result["cells"]}
    assert pairings == {"vdn vs vdn", "vdn vs qmix", "qmix vs qmix"}
    for cell in result["cells"]:
        assert cell["metric"] == "win_rate" and cell["reference_runs"] == 2
        assert 0 <= cell["reference_mean"] <= 100 and 0 <= cell["candidate_mean"] <= 100


@pytest.mark.slow
def test_a_tiny_field_study_tests_each_task_on_both_metrics(tmp_path: Path) -> None:
    """deep CMARL-CD's shares on both steps, one LBF task and simple_spread: each task a
    cell of both metrics, every run on its side, the family's margin, and the design
    named in the command."""
    done = study(
        "field", "--runs", "2", "--steps", "1k", "--eval-interval", "500", "--eval-episodes",
        "2", "--tasks", "foraging:5x5-2p-1f,simple_spread", "--workers", "1",
        "--out", str(tmp_path), "--markdown",
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    result = json.loads((tmp_path / "field.json").read_text())
    margins = {}
    for cell in result["cells"]:
        assert cell["reference_runs"] == cell["candidate_runs"] == 2
        margins[(cell["cell"].split(":")[0], cell["metric"])] = cell["margin"]
    assert margins == {
        (family, metric): margin
        for family, margin in (("foraging", 0.05), ("simple_spread", 3.0))
        for metric in ("average_return", "final_return")
    }
    assert "deep-cmarl-cd.design=shares-range-shared" in done.stdout
