"""``cmarl-cd merge`` as a user runs it: stores computed apart joined into one, and the
paths it refuses."""

from __future__ import annotations

import json
import subprocess
import sys

from cmarlcd.sweeps.store import ResultStore, RunKey


def cli(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "cmarlcd", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=600)


def report(store, figures) -> dict:
    done = cli("report", "--store", str(store), "--format", "json", "--figures", str(figures))
    assert done.returncode == 0, done.stderr
    document = json.loads(done.stdout)
    document.pop("store", None)
    return document


def test_two_seeds_computed_apart_read_as_one_sweep(tmp_path) -> None:
    """The same command at two seeds into two stores, merged into a third: its report is
    the one of both seeds computed into one store."""
    sweep = ["repeated", "--case", "1", "--agents", "2", "--actions", "2", "--runs", "2"]
    sweep += ["--workers", "1", "--no-progress", "--figures", str(tmp_path / "figures")]
    together = tmp_path / "together.sqlite"
    for seed in ("0", "1"):
        for store in (tmp_path / f"seed{seed}.sqlite", together):
            done = cli(*sweep, "--seed", seed, "--store", str(store))
            assert done.returncode == 0, done.stderr
    merged = tmp_path / "merged.sqlite"
    done = cli("merge", "--source", str(tmp_path / "seed0.sqlite"), "--source",
               str(tmp_path / "seed1.sqlite"), "--store", str(merged))  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith(f"merged {tmp_path / 'seed0.sqlite'}: 2 runs added, 0 already")
    assert lines[1].startswith(f"merged {tmp_path / 'seed1.sqlite'}: 2 runs added, 0 already")
    assert lines[2] == f"{merged}: 4 runs"
    strip = ("finished_at", "wall_seconds")
    with ResultStore(together, create=False) as a, ResultStore(merged, create=False) as b:
        ours = [(r.key, r.metrics) for r in a.records()]
        assert [(r.key, r.metrics) for r in b.records()] == ours
    assert {k: v for k, v in report(merged, tmp_path / "f").items() if k not in strip} == {
        k: v for k, v in report(together, tmp_path / "f").items() if k not in strip
    }


def test_a_second_merge_adds_nothing_and_says_which_runs_differ(tmp_path) -> None:
    a, b = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    key = RunKey("exp", "alg", "{}", 0, 0)
    with ResultStore(a) as store:
        store.put(key, {"v": 1}, 1.0, "x")
    with ResultStore(b) as store:
        store.put(key, {"v": 2}, 1.0, "x")
    done = cli("merge", "--source", str(a), "--store", str(b))
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[0] == (
        f"merged {a}: 0 runs added, 1 already in {b} (1 of them with other metrics; the "
        "store's kept)"
    )


def test_bad_sources_are_refused_in_one_line_before_anything_is_written(tmp_path) -> None:
    good, into = tmp_path / "good.sqlite", tmp_path / "into.sqlite"
    with ResultStore(good) as store:
        store.put(RunKey("exp", "alg", "{}", 0, 0), {"v": 1}, 1.0, "x")
    not_a_store = tmp_path / "notes.txt"
    not_a_store.write_text("hello\n")
    cases = {
        "no results store at": tmp_path / "missing.sqlite",
        "is not an SQLite database": not_a_store,
        "is the store itself": into,
    }
    for message, source in cases.items():
        if source == into:
            into.write_bytes(good.read_bytes())
        done = cli("merge", "--source", str(good), "--source", str(source), "--store", str(into))
        assert done.returncode == 2
        (line,) = done.stderr.strip().splitlines()
        assert line.startswith("error: --source: ") and message in line, line
        if source != into:
            assert not into.exists()  # the good source was not merged either
