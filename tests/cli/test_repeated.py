"""The ``repeated``, ``theory`` and ``play`` commands end to end on tiny budgets, the
console script over worker processes, and the counts every command reads."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cmarlcd.cli import parse_range
from cmarlcd.errors import ConfigError
from tests.cli.common import (
    assert_rejected_cleanly,
    invoke,
)


def test_parse_range_forms() -> None:
    assert parse_range("2-7", "agents", 2, 26) == (2, 3, 4, 5, 6, 7)
    assert parse_range("4", "agents", 2, 26) == (4,)
    assert parse_range("2,5, 3", "agents", 2, 26) == (2, 3, 5)
    with pytest.raises(ConfigError, match="reversed"):
        parse_range("7-2", "agents", 2, 26)
    with pytest.raises(ConfigError, match="LOW-HIGH"):
        parse_range("two", "agents", 2, 26)


def test_repeated_json_then_resume_then_report(paths) -> None:
    _, figures, where = paths
    args = [
        "repeated",
        "--case",
        "1",
        "--agents",
        "2-3",
        "--actions",
        "2",
        "--runs",
        "3",
        "--workers",
        "1",
        "--json",
        *where,
    ]
    first = invoke(*args)
    assert first.exit_code == 0, first.output
    doc = json.loads(first.stdout)
    assert [(c["agents"], c["actions"], c["runs"]) for c in doc["cells"]] == [(2, 2, 3), (3, 2, 3)]
    assert all(0.0 <= c["success_rate"] <= 1.0 and c["median_games"] > 0 for c in doc["cells"])
    assert doc["runs_computed"] == 6 and doc["runs_reused"] == 0
    assert Path(doc["figure"]).parent == figures and Path(doc["figure"]).stat().st_size > 10_000
    again = json.loads(invoke(*args).stdout)
    assert again["runs_computed"] == 0 and again["runs_reused"] == 6
    assert again["cells"] == doc["cells"]
    report = invoke("report", *where, "--json")
    assert report.exit_code == 0, report.output
    tables = json.loads(report.stdout)["repeated"]
    assert len(tables) == 1 and tables[0]["cells"] == doc["cells"]


def test_repeated_prints_the_paper_table(paths) -> None:
    _, _, where = paths
    result = invoke(
        "repeated",
        "--case",
        "2",
        "--agents",
        "4",
        "--actions",
        "3",
        "--runs",
        "2",
        "--workers",
        "1",
        "--no-progress",
        *where,
    )
    assert result.exit_code == 0, result.output
    assert "Table 2" in result.stdout and "100 (100)" in result.stdout


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--agents", "1-3"], "--agents"),
        (["--actions", "1"], "--actions"),
        (["--agents", "7-2"], "--agents"),
        (["--temperature", "0"], "--temperature"),
        (["--temperature", "-1"], "--temperature"),
        (["--delta", "0"], "--delta"),
        (["--delta", "1.5"], "--delta"),
        (["--runs", "0"], "--runs"),
        (["--case", "3"], "--case"),
        (["--workers", "0"], "--workers"),
        (["--max-games", "0"], "--max-games"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_stores_nothing(paths, args, option) -> None:
    store, figures, where = paths
    result = invoke("repeated", "--agents", "2", "--actions", "2", "--runs", "1", *where, *args)
    assert result.exit_code == 2
    assert_rejected_cleanly(result, option, store, figures)


def test_report_without_store_fails_cleanly(paths) -> None:
    result = invoke("report", *paths[2])
    assert result.exit_code == 2 and "no results store" in result.stderr


def test_theory_confirms_minus_two_over_t(paths) -> None:
    _, figures, _ = paths
    result = invoke(
        "theory",
        "--agents",
        "2",
        "--optima",
        "2",
        "--temperature",
        "0.5",
        "--starts",
        "10",
        "--json",
        "--figures",
        str(figures),
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["expected_eigenvalue"] == -4.0 and doc["max_eigen_error"] < 1e-6
    assert sum(doc["converged_to"]) == 10 and doc["confirmed"]
    assert (figures / "theorem1-phase-T0.5.png").exists()


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--agents", "1"], "--agents"),
        (["--optima", "1"], "--optima"),
        (["--temperature", "0"], "--temperature"),
        (["--starts", "0"], "--starts"),
    ],
)
def test_theory_bad_input(args, option) -> None:
    result = invoke("theory", *args)
    assert result.exit_code == 2 and result.stderr.startswith(f"error: {option}:")


def test_play_learns_a_user_game(tmp_path) -> None:
    game = tmp_path / "climbing.json"
    game.write_text("[[11, -30, 0], [-30, 7, 6], [0, 0, 5]]")
    result = invoke("play", "--payoffs", str(game), "--runs", "4", "--json")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    assert doc["optimal_joint_actions"] == [[0, 0]] and doc["success_rate"] == 1.0


@pytest.mark.parametrize(
    ("content", "fragment"),
    [
        ("[[1, 2], [3, NaN]]", "finite"),
        ("[[1, 2], [3", "cannot read"),
        ("[1, 2, 3]", "one axis per agent"),
    ],
)
def test_play_rejects_bad_payoffs(tmp_path, content, fragment) -> None:
    game = tmp_path / "bad.json"
    game.write_text(content)
    result = invoke("play", "--payoffs", str(game))
    assert result.exit_code == 2
    assert result.stderr.startswith("error: --payoffs:") and fragment in result.stderr


def test_console_script_runs_a_sweep_over_worker_processes(tmp_path) -> None:
    """The real entry point, with a process pool of 2 workers."""
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "cmarlcd",
            "repeated",
            "--case",
            "2",
            "--agents",
            "4",
            "--actions",
            "3-4",
            "--runs",
            "4",
            "--workers",
            "2",
            "--json",
            "--store",
            str(tmp_path / "s.sqlite"),
            "--figures",
            str(tmp_path / "f"),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    doc = json.loads(out.stdout)
    assert doc["runs_computed"] == 8 and len(doc["cells"]) == 2


@pytest.mark.parametrize(
    ("text", "value"),
    [("50000", 50_000), ("100_000", 100_000), ("50k", 50_000), ("2.05M", 2_050_000),
     ("2M", 2_000_000), ("1.5k", 1_500), (" 7 ", 7)],
)  # fmt: skip
def test_counts_with_suffixes(text, value) -> None:
    from cmarlcd.cli.options import parse_count

    assert parse_count(text, "steps") == value


@pytest.mark.parametrize(
    "text", ["0", "-5k", "0.5", "1.2345k", "2.0000005M", "abc", "nanM", "k", ""]
)
def test_counts_that_are_not_whole_or_positive_are_refused(text) -> None:
    from cmarlcd.cli.options import parse_count
    from cmarlcd.errors import ConfigError

    with pytest.raises(ConfigError):
        parse_count(text, "steps")
