"""Helpers shared by the tests (imported as `tests.helpers`)."""

from __future__ import annotations

import contextlib
import json
import sqlite3
from pathlib import Path

from cmarlcd.sweeps.store import ResultStore, RunKey


def not_a_store(tmp_path, kind: str):
    """A path that cannot be a results store, and the words the error must contain."""
    if kind == "directory":
        return tmp_path, "is a directory"
    if kind == "under a file":
        (tmp_path / "plain.txt").write_text("hello")
        return tmp_path / "plain.txt" / "store.sqlite", "is a file, not a directory"
    if kind == "not sqlite":
        (tmp_path / "notes.sqlite").write_text("just some text, not a database\n" * 10)
        return tmp_path / "notes.sqlite", "not an SQLite database"
    if kind == "truncated":
        path = tmp_path / "cut.sqlite"
        with ResultStore(path) as store:
            for i in range(300):
                store.put(RunKey("e", "a", "{}", 0, i), {"values": list(range(50))}, 0.1, "x")
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        for extra in ("-wal", "-shm"):
            path.with_name(path.name + extra).unlink(missing_ok=True)
        return path, "damaged"
    if kind == "another program's":
        path = tmp_path / "other.sqlite"
        conn = sqlite3.connect(path)
        conn.execute("CREATE TABLE people (name TEXT)")
        conn.commit()
        conn.close()
        return path, "not a cmarl-cd results store"
    if kind == "unwritable":
        return Path("/proc/cmarl-cd-test/store.sqlite"), "cannot"
    raise AssertionError(kind)


STORE_PROBLEMS = [
    "directory",
    "under a file",
    "not sqlite",
    "truncated",
    "another program's",
    "unwritable",
]


def fill_the_disk(monkeypatch, pages_left: int = 0) -> None:
    """Every store opened from now on finds its disk full after ``pages_left`` more pages
    (SQLite's own page limit: its writes then fail as on a full disk, SQLITE_FULL)."""
    opened = ResultStore.__init__

    def full(self, *args, **kwargs) -> None:
        opened(self, *args, **kwargs)
        pages = self._conn.execute("PRAGMA page_count").fetchone()[0]
        self._conn.execute(f"PRAGMA max_page_count = {pages + pages_left}")

    monkeypatch.setattr(ResultStore, "__init__", full)


def stored(store: Path) -> dict[tuple, str]:
    """Every run of a store without its timings: key -> metrics (JSON text), read-only."""
    query = "SELECT experiment, algorithm, config, root_seed, run_index, metrics FROM runs"
    with contextlib.closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True)) as conn:
        rows = conn.execute(query).fetchall()
    out = {}
    for *key, metrics in rows:
        values = {
            k: v
            for k, v in json.loads(metrics).items()
            if k != "seconds" and not k.endswith("_seconds")
        }
        out[tuple(key)] = json.dumps(values, sort_keys=True)
    return out
