"""What a new user ran into, across the commands: bad stores and figure folders, absurd
values, payoff files that are not games, the help's words, backends, full disks."""

from __future__ import annotations

import importlib.util
import json
import time
from pathlib import Path

import numpy as np
import pytest

from cmarlcd import __version__
from cmarlcd.sweeps.store import ResultStore
from tests.cli.common import (
    HANG,
    assert_rejected_cleanly,
    invoke,
    small_repeated,
)
from tests.helpers import STORE_PROBLEMS, not_a_store

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
