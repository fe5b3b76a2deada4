"""The command line end to end, on tiny budgets."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cmarlcd import __version__
from cmarlcd.cli import app, parse_range
from cmarlcd.errors import ConfigError
from cmarlcd.sweeps.store import ResultStore
from tests.helpers import STORE_PROBLEMS, not_a_store

runner = CliRunner()
#: Seconds that tell a hang from a refusal: a refusal takes milliseconds, what it guards
#: against minutes; the bound is loose so that a loaded machine never fails the test.
HANG = 20


def invoke(*args: str):
    return runner.invoke(app, list(args))


@pytest.fixture
def paths(tmp_path):
    store, figures = tmp_path / "store.sqlite", tmp_path / "figures"
    return store, figures, ["--store", str(store), "--figures", str(figures)]


def assert_rejected_cleanly(result, option: str, store, figures) -> None:
    """Exit 2, one line naming the option, nothing written."""
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {option}:"), result.stderr
    assert not store.exists() and not figures.exists()


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


def tiny_reproduction(paths, monkeypatch):
    """``reproduce`` of a tiny preset into ``paths``; returns its JSON document."""
    from cmarlcd.cli import reproduce as cli

    monkeypatch.setitem(cli.PRESETS, "quick", cli.PRESETS["smoke"])  # the default preset
    result = invoke("reproduce", "--workers", "1", "--json", *paths[2])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


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


def without_torch(monkeypatch) -> None:
    """Make the CLI see an install without the [deep] extra."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "torch" else real(name, *a)
    )


def tiny_paper_preset(monkeypatch) -> None:
    from cmarlcd.cli import reproduce as cli

    tiny = cli.Preset(
        1,
        1,
        dsn_eval_episodes=20,
        dsn_episodes=(30,),
        deep=True,
        tournament_rounds=1,
        tournament_episodes=20,
        compare_runs=1,
        compare_games=("climbing", "dsn"),
        compare_dsn_episodes=100,
    )
    monkeypatch.setitem(cli.PRESETS, "paper", tiny)


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


def test_dsn_deep_without_torch_names_the_extra(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    store, _, where = paths
    result = invoke("dsn", "--algorithms", "cmarl-cd,qmix", "--episodes", "10", *where)
    assert result.exit_code == 2 and "cmarl-cd[deep]" in result.stderr
    assert not store.exists()


def test_compare_deep_without_torch_names_the_extra(paths, monkeypatch) -> None:
    without_torch(monkeypatch)
    store, _, where = paths
    result = invoke("compare", "--learners", "deep-cmarl-cd", "--games", "climbing", *where)
    assert result.exit_code == 2 and "cmarl-cd[deep]" in result.stderr
    assert not store.exists()


# ---------------------------------------------------- what a new user ran into


TINY = {
    "repeated": ["repeated", "--agents", "2", "--actions", "2", "--runs", "1", "--workers", "1"],
    "dsn": ["dsn", "--episodes", "20", "--runs", "1", "--eval-episodes", "10", "--workers", "1"],
    "reproduce": ["reproduce", "--workers", "1"],
    "report": ["report"],
}


@pytest.mark.parametrize("command", list(TINY))
@pytest.mark.parametrize("kind", STORE_PROBLEMS)
def test_every_command_refuses_a_bad_store_in_one_line(tmp_path, command, kind) -> None:
    store, words = not_a_store(tmp_path, kind)
    if command == "report" and kind == "unwritable":
        words = "no results store"  # report only reads
    before = store.read_bytes() if store.is_file() else None
    figures = tmp_path / "figs"
    result = invoke(*TINY[command], "--store", str(store), "--figures", str(figures))
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --store:") and words in lines[0]
    assert (store.read_bytes() if store.is_file() else None) == before  # never modified
    assert not figures.exists()  # nothing computed


def test_a_bad_figures_folder_is_refused_before_anything_is_computed(paths, tmp_path) -> None:
    store, _, _ = paths
    (tmp_path / "taken").write_text("a file where the figures should go")
    for figures in (tmp_path / "taken", tmp_path / "taken" / "sub"):
        result = invoke(*TINY["repeated"], "--store", str(store), "--figures", str(figures))
        assert result.exit_code == 2 and result.stderr.startswith("error: --figures:")
        assert "is a file, not a directory" in result.stderr
        assert not store.exists()


def test_figures_are_named_by_their_settings(paths) -> None:
    _, figures, where = paths
    base = ["repeated", "--agents", "2", "--actions", "2", "--runs", "2", "--workers", "1"]
    one = invoke(*base, "--json", *where)
    two = invoke(*base, "--temperature", "0.5", "--json", *where)
    first, second = json.loads(one.stdout)["figure"], json.loads(two.stdout)["figure"]
    assert first != second and Path(first).exists() and Path(second).exists()
    text = invoke("report", *where).stdout
    assert f"figure: {first} (case 1, T=1, δ=0.04, seed 0, 2 runs per cell)" in text
    assert f"figure: {second} (case 1, T=0.5" in text
    assert len(list(figures.glob("repeated-*.png"))) == 2


def test_settings_other_than_the_paper_s_are_not_shown_beside_the_paper(paths) -> None:
    _, _, where = paths
    base = ["repeated", "--case", "2", "--agents", "4", "--actions", "3", "--runs", "2"]
    paper = invoke(*base, "--workers", "1", "--no-progress", *where).stdout
    assert "2 runs per cell" in paper and "ours (the paper's)" in paper and "(100)" in paper
    other = invoke(*base, "--delta", "0.05", "--workers", "1", "--no-progress", *where).stdout
    assert "settings differ from the paper's" in other and "(100)" not in other
    assert other.strip().splitlines()[-1].startswith("results: runs in ")


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


@pytest.mark.parametrize(
    ("args", "option", "words"),
    [
        (["repeated", "--agents", "99999999999999999999"], "--agents", "must be <= 26"),
        (["repeated", "--agents", "2-30000000"], "--agents", "must be <= 26"),
        (["repeated", "--agents", "20", "--actions", "5"], "--agents", "exceed the limit"),
        (["repeated", "--agents", ""], "--agents", "expected N, LOW-HIGH"),
        (["repeated", "--actions", "2,,3"], "--actions", "expected N, LOW-HIGH"),
        (["report", "--case", "3"], "--case", "must be 1 or 2"),
        (["theory", "--agents", "50", "--optima", "50"], "--agents", "exceed"),
        (["dsn", "--eval-episodes", "lots"], "--eval-episodes", "expected an integer"),
        (["dsn", "--algorithms", " , "], "--algorithms", "needs at least one"),
    ],
)
def test_absurd_or_empty_values_fail_at_once(paths, args, option, words) -> None:
    store, figures, where = paths
    start = time.perf_counter()
    result = invoke(*args, *where) if args[0] != "theory" else invoke(*args)
    assert time.perf_counter() - start < HANG  # milliseconds; an expanded range: minutes
    assert_rejected_cleanly(result, option, store, figures)
    assert words in result.stderr


def test_payoff_files_that_cannot_be_games_say_why(tmp_path) -> None:
    huge = tmp_path / "huge.npy"
    with huge.open("wb") as file:  # a header that promises 10^5 x 10^5 doubles, no data
        np.lib.format.write_array_header_1_0(
            file, {"descr": "<f8", "fortran_order": False, "shape": (100_000, 100_000)}
        )
    (tmp_path / "empty.npy").touch()
    cases = [
        (huge, "more than 100,000,000 joint actions"),
        (tmp_path / "empty.npy", "empty.npy is empty"),
        (tmp_path, "is a directory"),
    ]
    for path, words in cases:
        start = time.perf_counter()
        result = invoke("play", "--payoffs", str(path))
        assert time.perf_counter() - start < HANG  # reading 80 GB would take minutes
        assert result.exit_code == 2 and result.stderr.startswith("error: --payoffs:")
        assert words in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_help_keeps_its_words_and_shows_flags_as_flags() -> None:
    repeated_help = invoke("repeated", "--help").stdout
    words = " ".join(repeated_help.split())  # as wrapped to the terminal's width
    assert "[default: all cores]" in words and "[default: the paper's]" in words
    assert "[deep]" in " ".join(invoke("reproduce", "-h").stdout.split())
    flag = next(line for line in repeated_help.splitlines() if "--json" in line)
    assert "<" not in flag  # no value
    assert invoke("--version").stdout.strip() == f"cmarl-cd {__version__}"
    assert "Commands:" in invoke("-h").stdout
    dsn_help = " ".join(invoke("dsn", "--help").stdout.split())
    assert "[default: 0.05]" in dsn_help and "[default: 0.1]" in dsn_help  # from the configs


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


# ------------------------------------------------- backends, write failures, report


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--backend", "spark"], "--backend"),
        (["--address", "ray://head:10001"], "--address"),
        (["--backend", "ray", "--address", " "], "--address"),
    ],
)
def test_bad_backend_choices_fail_at_once(paths, args, option) -> None:
    store, figures, where = paths
    for command in ("repeated", "dsn", "tournament", "reproduce"):
        result = invoke(command, *where, *args)
        assert_rejected_cleanly(result, option, store, figures)


def test_ray_backend_without_ray_names_the_extra(paths, monkeypatch) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name, *a)
    )
    store, figures, where = paths
    result = invoke("repeated", "--runs", "1", "--backend", "ray", *where)
    assert_rejected_cleanly(result, "--backend", store, figures)
    assert "pip install 'cmarl-cd[ray]'" in result.stderr


def small_repeated(where: list[str], runs: str = "2") -> object:
    args = ("--agents", "2-3", "--actions", "2", "--runs", runs, "--no-progress")
    return invoke("repeated", *args, *where)


def test_a_full_disk_during_a_sweep_is_one_line_and_keeps_the_stored_runs(
    paths, monkeypatch
) -> None:
    from tests.helpers import fill_the_disk

    store, _, where = paths
    assert small_repeated(where, "1").exit_code == 0
    with ResultStore(store) as db:
        before = [(r.key, r.metrics) for r in db.records()]
    fill_the_disk(monkeypatch)
    args = ("--agents", "2-4", "--actions", "2-3", "--runs", "40", "--no-progress")
    result = invoke("repeated", *args, *where)
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: --store: cannot write"), result.stderr
    assert "database or disk is full" in lines[0]
    monkeypatch.undo()
    with ResultStore(store) as db:  # the runs stored before (and until the disk filled)
        after = [(r.key, r.metrics) for r in db.records()]
        assert set(map(repr, before)) <= set(map(repr, after)) and len(after) < 6 * 40


def test_a_full_disk_while_drawing_a_figure_is_one_line(paths, monkeypatch) -> None:
    import errno

    from cmarlcd.reports import figures as figs

    def no_space(fig, path):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(figs, "_save", no_space)
    result = small_repeated(paths[2])
    assert result.exit_code == 2
    assert result.stderr.strip().startswith("error: cannot write ")
    assert result.stderr.strip().endswith("No space left on device")


SECTIONS = ("Table 1", "Table 2", "Tables 3-7", "Figs. 6-7", "Theorem 1", "Comparison")


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


@pytest.mark.slow
def test_report_renders_every_section_in_every_format(paths, monkeypatch, tmp_path) -> None:
    store, _, where = paths
    tiny_reproduction(paths, monkeypatch)
    markdown = tmp_path / "out" / "report.md"
    result = invoke("report", *where, "--format", "markdown", "--output", str(markdown))
    assert result.exit_code == 0, result.output
    text = markdown.read_text()
    for section in SECTIONS:
        assert f"## {section}" in text
    assert "(100)" in text  # the paper's value beside ours (Table 1: 100 %)
    assert f"computed by cmarl-cd {__version__}" in text
    assert "1 stored run" in text and "runs per cell" in text
    for link in [line.split("](")[1][:-1] for line in text.splitlines() if line.startswith("![")]:
        assert (markdown.parent / link).is_file(), link  # figures linked from the file's folder
    html = invoke("report", *where, "--format", "html")
    assert html.exit_code == 0
    for section in SECTIONS:
        assert f"<h2>{section}" in html.stdout
    doc = json.loads(invoke("report", *where, "--format", "json").stdout)
    assert {len(doc[k]) for k in ("repeated", "dsn", "tournament", "theorem1", "compare")} >= {1}
    assert doc["versions"] == {__version__: sum(1 for _ in ResultStore(store).records())}


@pytest.mark.slow
def test_the_html_report_opens_with_no_other_file(paths, monkeypatch, tmp_path) -> None:
    import re

    tiny_reproduction(paths, monkeypatch)
    page = tmp_path / "report.html"
    assert invoke("report", *paths[2], "--format", "html", "--output", str(page)).exit_code == 0
    html = page.read_text()
    sources = re.findall(r'(?:src|href)="([^"]*)"', html)
    assert sources and all(s.startswith("data:image/png;base64,") for s in sources)
    assert "<link" not in html and "<script" not in html and "url(" not in html
    figures = sorted(paths[1].glob("*.png"))
    assert len(sources) == len(figures)  # every figure drawn is in the page


def test_a_report_that_mixes_versions_says_so(paths) -> None:
    store, _, where = paths
    assert small_repeated(where).exit_code == 0
    with ResultStore(store) as db:
        db._conn.execute("UPDATE runs SET version = '0.0.1' WHERE run_index = 0")
    text = invoke("report", *where)
    assert "mix package versions (0.0.1, " in " ".join(text.stdout.split())
    markdown = invoke("report", *where, "--format", "markdown").stdout
    assert "mix package versions" in markdown and "0.0.1 (2 runs)" in markdown


@pytest.mark.parametrize(
    ("args", "option"),
    [(["--format", "pdf"], "--format"), (["--output", "."], "--output")],
)
def test_report_bad_format_or_output(paths, args, option) -> None:
    _, _, where = paths
    assert small_repeated(where).exit_code == 0
    result = invoke("report", *where, *args)
    assert result.exit_code == 2 and result.stderr.startswith(f"error: {option}:")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_a_report_that_cannot_be_written_is_one_line(paths) -> None:
    """/proc takes no new file, even from root (for whom os.access says it could)."""
    _, _, where = paths
    assert small_repeated(where).exit_code == 0
    result = invoke("report", *where, "--format", "html", "--output", "/proc/report.html")
    assert result.exit_code == 2
    assert result.stderr.startswith("error:") and "/proc" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


# ------------------------------------------------------------------------ compare


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
