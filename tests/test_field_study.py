"""The field study's script and its tables (benchmarks/field_study.sh,
benchmarks/field_study_tables.py): a hand-built report's figures land in their cells, the
row's best in bold, what the store lacks listed; bad input is one line and status 2."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "benchmarks/field_study_tables.py"
spec = importlib.util.spec_from_file_location("field_study_tables", SCRIPT)
assert spec is not None and spec.loader is not None
tables = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tables)


def figures(best: float, average: float) -> dict[str, float]:
    return {
        "max_return": best, "max_return_low": best - 0.1, "max_return_high": best + 0.1,
        "average_return": average, "average_return_low": float("nan"),
        "average_return_high": float("nan"),
    }  # fmt: skip


REPORT = {
    "train": [
        {
            "game": "foraging:8x8-2p-2f-coop",
            "rows": [{"algorithm": "random", "mean_return": 0.005}],
            "field": {
                "VDN (EPyMARL, share=True)": figures(0.4, 0.2),
                "QMIX (EPyMARL, share=True)": figures(0.4, 0.1),
                "Deep CMARL-CD (gamma=0.99)": figures(0.1, 0.3),
                "VDN (some other setting)": figures(0.9, 0.9),
                # the design the study's replaced (shares-cold): in no column
                "Deep CMARL-CD (critic_bootstrap='greedy', critic_form='degrees', "
                "gamma=0.99)": figures(0.8, 0.8),
            },
            "curves": {
                "VDN (EPyMARL, share=True)": [[[0, 0.0], [50, 0.2]], [[0, 0.2], [50, 0.6]]],
                "random policy": [[[0, 0.005], [50, 0.005]]],
            },
        },
        {"game": "foraging:5x5-2p-1f", "rows": [], "field": {}, "curves": {}},
        {
            "game": "simple_spread:N=3,local_ratio=0.5,max_cycles=25",
            "rows": [{"algorithm": "random", "mean_return": -79.3}],
            "field": {
                "VDN (EPyMARL, share=True)": figures(-50.0, -60.0),
                "Deep CMARL-CD (critic_bootstrap='greedy', critic_form='degrees', gamma=0.99, "
                "standardise_rewards=True, step='fused')": figures(-40.0, -70.0),
            },
            "curves": {},
        },
    ]
}


def test_cells_best_and_floor() -> None:
    tasks = tables.study(REPORT)
    # a task outside the study is left out; simple_spread is found by its stored name
    assert list(tasks) == ["foraging:8x8-2p-2f-coop", "simple_spread"]
    best = tables.table(tasks, "max_return")
    row = best[2].split(" | ")
    # IQL, hysteretic DQN: absent; VDN and QMIX tie at the best; a label outside the
    # study's columns (0.9) is not a column; VDN's two curves are 2 of the study's 5
    # seeds, QMIX shows no curves to count
    assert row[1:3] == ["–", "–"]
    assert row[3] == "**0.400** [0.300, 0.500] (2 of 5 seeds)"
    assert row[4] == "**0.400** [0.300, 0.500]"
    assert row[5] == "0.100 [0.000, 0.200]" and row[7] == "0.005 |"
    average = tables.table(tasks, "average_return")[2].split(" | ")
    assert average[5] == "**0.300**" and average[3] == "0.200 (2 of 5 seeds)"  # no interval
    # at a protocol of two seeds VDN's cell holds them all
    assert tables.table(tasks, "max_return", expected=2)[2].split(" | ")[3] == (
        "**0.400** [0.300, 0.500]"
    )
    assert tasks["foraging:8x8-2p-2f-coop"]["curves"]["VDN"] == [(0, 0.1), (50, 0.4)]


def test_missing_pairs_are_listed() -> None:
    absent = tables.missing(tables.study(REPORT))
    assert absent[0] == (
        "foraging:8x8-2p-2f-coop: IQL, hysteretic DQN, VDN (2 of 5 seeds), deep CMARL-CD (shares)"
    )
    assert tables.missing(tables.study(REPORT), expected=2)[0] == (
        "foraging:8x8-2p-2f-coop: IQL, hysteretic DQN, deep CMARL-CD (shares)"
    )
    assert len(absent) == len(tables.TASKS)
    assert absent[-1] == "simple_spread: IQL, hysteretic DQN, QMIX, deep CMARL-CD"


def test_the_design_column_holds_the_study_s_design_only() -> None:
    """The shares with standardised rewards fill the design's column; the design they
    replaced, whose runs stay in the store, fills none."""
    tasks = tables.study(REPORT)
    assert "deep CMARL-CD (shares)" not in tasks["foraging:8x8-2p-2f-coop"]["field"]
    spread = tables.table(tasks, "max_return")[3].split(" | ")
    assert spread[6] == "**-40.000** [-40.100, -39.900]" and spread[3].startswith("-50.000")


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, check=False
    )


def test_the_script_prints_the_tables_and_draws(tmp_path: Path) -> None:
    report = tmp_path / "report.json"
    report.write_text(json.dumps(REPORT))
    done = run("--report", str(report), "--figure", str(tmp_path / "curves.png"))
    assert done.returncode == 0, done.stderr
    assert "| 8x8-2p-2f-coop | – | – | **0.400**" in done.stdout
    assert (tmp_path / "curves.png").stat().st_size > 0


def test_the_page_blocks_are_filled(tmp_path: Path) -> None:
    page = "intro\n<!-- study-max -->\nold\n<!-- /study-max -->\nafter\n"
    assert tables.fill(page, "study-max", ["| a |", "| b |"]) == (
        "intro\n<!-- study-max -->\n| a |\n| b |\n<!-- /study-max -->\nafter\n"
    )
    report, doc = tmp_path / "report.json", tmp_path / "field.md"
    report.write_text(json.dumps(REPORT))
    blocks = ("study-max", "study-average", "study-missing")
    doc.write_text("".join(f"<!-- {b} -->\n<!-- /{b} -->\n" for b in blocks))
    assert run("--report", str(report), "--page", str(doc)).returncode == 0
    text = doc.read_text()
    assert "| 8x8-2p-2f-coop | – | – | **0.400** [0.300, 0.500]" in text
    average = "| 8x8-2p-2f-coop | – | – | 0.200 (2 of 5 seeds) | 0.100 | **0.300** | – | 0.005 |"
    assert average in text
    assert "- simple_spread: IQL, hysteretic DQN, QMIX" in text
    assert "| simple_spread | – | – | -50.000 [-50.100, -49.900] | – | – | **-40.000**" in text
    doc.write_text("no blocks here\n")
    done = run("--report", str(report), "--page", str(doc))
    assert done.returncode == 2
    assert done.stderr.strip() == (
        f"error: {doc}: the page has no block <!-- study-max --> ... <!-- /study-max -->"
    )


def test_hours_sum_each_tasks_runs_by_learner(tmp_path: Path) -> None:
    import sqlite3

    store = tmp_path / "s.sqlite"
    spread = '{"game": {"task": "N=3,local_ratio=0.5,max_cycles=25"}}'
    rows = [  # (experiment, algorithm, config, wall seconds)
        ("foraging", "vdn", '{"game": {"task": "8x8-2p-2f-coop"}}', 1800.0),
        ("foraging", "vdn", '{"game": {"task": "8x8-2p-2f-coop"}}', 1800.0),
        ("foraging", "deep-cmarl-cd", '{"game": {"task": "8x8-2p-2f-coop"}}', 3600.0),
        ("foraging", "deep-cmarl-cd", '{"game": {"task": "8x8-2p-2f-coop"}, "learner": '
         '{"critic_form": "degrees", "standardise_rewards": true}}', 7200.0),
        ("foraging", "deep-cmarl-cd",  # the design the study's replaced: no column
         '{"game": {"task": "8x8-2p-2f-coop"}, "learner": {"critic_form": "degrees"}}', 500.0),
        ("simple_spread", "qmix", spread, 900.0),
        ("foraging", "vdn", '{"game": {"task": "5x5-2p-1f"}}', 99.0),  # not the study's
    ]  # fmt: skip
    with sqlite3.connect(store) as db:
        db.execute("CREATE TABLE runs (experiment, algorithm, config, wall_seconds)")
        db.executemany("INSERT INTO runs VALUES (?, ?, ?, ?)", rows)
    spent = tables.hours(store)
    assert spent == {
        "foraging:8x8-2p-2f-coop": {
            "VDN": 1.0,
            "deep CMARL-CD": 1.0,
            "deep CMARL-CD (shares)": 2.0,
        },
        "simple_spread": {"QMIX": 0.25},
    }
    table = tables.time_table(spent)
    assert table[2] == "| 8x8-2p-2f-coop | – | – | 1.00 | – | 1.00 | 2.00 | 4.00 |"
    assert table[-1] == "| all | 0.00 | 0.00 | 1.00 | 0.25 | 1.00 | 2.00 | 4.25 |"


def test_bad_input_is_one_line(tmp_path: Path) -> None:
    done = run("--report", str(tmp_path / "absent.json"))
    assert done.returncode == 2 and done.stderr.strip().startswith("error: no such file")
    done = run()
    assert done.returncode == 2 and done.stderr.strip() == "error: give one of --store and --report"
    text = tmp_path / "text.json"
    text.write_text("not JSON")
    done = run("--report", str(text))
    assert done.returncode == 2
    assert done.stderr.strip() == f"error: {text} is not a report (cmarl-cd report --format json)"
    done = run("--store", str(text))
    assert done.returncode == 2 and done.stderr.strip().startswith("error: --store:")
    done = run("--report", str(text), "--seeds", "0")
    assert done.returncode == 2 and done.stderr.strip() == "error: --seeds must be >= 1 (got 0)"
    shell = subprocess.run(
        ["bash", str(ROOT / "benchmarks/field_study.sh"), "fast", str(tmp_path)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert shell.returncode == 2
    assert shell.stderr.strip() == "error: unknown form 'fast' (full or quick)"
    for env, line in (
        ({"PARTS": "vdn iql"}, "error: unknown part 'iql' (shares vdn deep-cmarl-cd qmix "
                               "deep-iql hysteretic-dqn)"),
        ({"WORKERS": "0"}, "error: WORKERS must be >= 1 (got '0')"),
    ):  # fmt: skip
        shell = subprocess.run(
            ["bash", str(ROOT / "benchmarks/field_study.sh"), "quick", str(tmp_path)],
            capture_output=True, text=True, check=False, env={**os.environ, **env},
        )  # fmt: skip
        assert shell.returncode == 2 and shell.stderr.strip() == line
    assert not (tmp_path / "store.sqlite").exists()  # refused before anything ran


def test_the_study_s_extra_settings_reach_the_learner(tmp_path: Path) -> None:
    """``SET`` is appended to the part's own settings: a setting the learner lacks is
    refused by ``cmarl-cd field`` in one line, before anything is stored."""
    shell = subprocess.run(
        ["bash", str(ROOT / "benchmarks/field_study.sh"), "quick", str(tmp_path), "simple_spread"],
        capture_output=True, text=True, check=False,
        env={**os.environ, "PARTS": "vdn", "SET": "vdn.standardise=false"},
    )  # fmt: skip
    assert shell.returncode == 2
    last = shell.stderr.strip().splitlines()[-1]
    assert last.startswith("error: --set: vdn has no setting 'standardise'"), shell.stderr
    assert not (tmp_path / "store.sqlite").exists()
