"""Where a run was computed: every stored run records it, an older store's runs read as
unrecorded, and the report says it once per store or names what differs."""

from __future__ import annotations

import json
import sqlite3
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pytest

from cmarlcd import provenance
from cmarlcd.runs import RunKey
from cmarlcd.sweeps.store import ResultStore

ROOT = Path(__file__).resolve().parents[1]
V3 = {"cx16", "sahf", "popcnt", "sse3", "sse4.1", "sse4.2", "ssse3", "avx", "avx2", "bmi",
      "bmi2", "f16c", "fma", "lzcnt", "movbe"}  # fmt: skip


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cmarlcd", *args], capture_output=True,
                          text=True, timeout=600, cwd=ROOT)  # fmt: skip


@pytest.mark.parametrize(
    ("features", "machine", "level"),
    [
        (V3, "x86_64", "x86-64-v3"),
        (V3 - {"fma"}, "x86_64", "x86-64-v2"),  # no FMA: not v3
        (V3 | {"avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl"}, "x86_64",
         "x86-64-v4"),
        ({"sse3"}, "x86_64", "x86-64"),
        (V3, "aarch64", "aarch64"),
    ],
)  # fmt: skip
def test_the_instruction_set_level_of_a_cpu(features, machine, level) -> None:
    assert provenance.isa_level(features, machine) == level


def test_every_stored_run_records_where_it_was_computed(tmp_path) -> None:
    store = tmp_path / "s.sqlite"
    done = cli("repeated", "--runs", "3", "--workers", "1", "--no-progress", "--store",
               str(store))  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    with ResultStore(store, create=False) as db:
        found = db.provenances()
        runs = db.count()
    assert len(found) == 1 and found[0][1] == runs > 0
    info = found[0][0]
    assert info["numpy"] == np.__version__ and info["numba"] == numba.__version__
    assert info["torch"] is None and info["device"] == "cpu"  # a table learner's run
    assert info["cpu_target"] and info["isa_level"] and info["python"]
    report = json.loads(cli("report", "--store", str(store), "--format", "json").stdout)
    assert report["provenance"] == [{"runs": runs, **info}]
    text = cli("report", "--store", str(store)).stdout
    assert f"computed with cmarl-cd {info['cmarl_cd']}, Python {info['python']}" in text


def test_a_store_of_an_older_version_reads_its_runs_as_unrecorded(tmp_path) -> None:
    """A store written before provenance was recorded (no provenance tables): its runs
    read as unrecorded, new runs beside them record theirs, and the report says both."""
    store = tmp_path / "old.sqlite"
    with ResultStore(store) as db:
        db.put(RunKey("repeated", "cmarl-cd", "{}", 0, 0), {"x": 1}, 0.1, "0.5.0")
    with sqlite3.connect(store) as conn:  # as 0.6.0 left it
        conn.execute("DROP TABLE run_provenance")
        conn.execute("DROP TABLE provenances")
    with ResultStore(store) as db:
        assert db.provenances() == [(None, 1)]
        a = {"cmarl_cd": "0.7.0", "cpu": "A", "numpy": "2.4.6"}
        db.put(RunKey("repeated", "cmarl-cd", "{}", 0, 1), {"x": 2}, 0.1, "0.7.0", a)
        db.put(RunKey("repeated", "cmarl-cd", "{}", 0, 2), {"x": 3}, 0.1, "0.7.0", a)
        db.put(RunKey("repeated", "cmarl-cd", "{}", 0, 3), {"x": 3}, 0.1, "0.7.0",
               {**a, "cpu": "B"})  # fmt: skip
        found = db.provenances()
    assert sorted(found, key=str) == sorted([(None, 1), (a, 2), ({**a, "cpu": "B"}, 1)], key=str)
    lines = provenance.store_lines(found)
    assert lines[0] == "runs of this store were computed in different places (they differ in cpu):"
    assert "  1 runs: no provenance recorded (stored before it was)" in lines


def test_a_run_stored_twice_keeps_its_first_provenance(tmp_path) -> None:
    key = RunKey("repeated", "cmarl-cd", "{}", 0, 0)
    with ResultStore(tmp_path / "s.sqlite") as db:
        assert db.put(key, {"x": 1}, 0.1, "0.7.0", {"cpu": "first"})
        assert not db.put(key, {"x": 1}, 0.1, "0.7.0", {"cpu": "second"})
        assert db.provenances() == [({"cpu": "first"}, 1)]


def test_deep_and_table_runs_of_one_machine_are_one_place() -> None:
    table = {"cmarl_cd": "0.7.0", "cpu": "A", "torch": None, "device": "cpu"}
    deep = {**table, "torch": "2.13.0+cpu"}
    assert provenance.store_lines([(table, 5), (deep, 2)]) == [
        "computed with " + provenance.describe(deep)
    ]


def test_reading_an_older_store_leaves_its_file_as_it_was(tmp_path) -> None:
    """A report of a store committed by an older version (no provenance tables) reads it
    without adding them: the file stays byte for byte what was committed."""
    store = tmp_path / "old.sqlite"
    done = cli("repeated", "--runs", "2", "--workers", "1", "--no-progress", "--store",
               str(store))  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    with sqlite3.connect(store) as conn:  # as 0.6.0 left it
        conn.execute("DROP TABLE run_provenance")
        conn.execute("DROP TABLE provenances")
    with sqlite3.connect(store) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    before = store.read_bytes()
    report = cli("report", "--store", str(store), "--format", "json")
    assert report.returncode == 0, report.stderr[-2000:]
    with ResultStore(store, create=False) as db:
        runs = db.count()
        assert runs > 0 and db.provenances() == [(None, runs)]
    assert [row["runs"] for row in json.loads(report.stdout)["provenance"]] == [runs]
    assert store.read_bytes() == before
    with sqlite3.connect(store) as conn:
        tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master")}
    assert "provenances" not in tables and "runs" in tables
