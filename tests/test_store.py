"""The SQLite results store."""

from __future__ import annotations

import sqlite3

import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.sweeps.store import ResultStore, RunKey, StoreWriteError, canonical_json
from tests.helpers import STORE_PROBLEMS, fill_the_disk, not_a_store


def key(index: int, config: str = '{"a":1}') -> RunKey:
    return RunKey("exp", "alg", config, 0, index)


def test_canonical_json_ignores_key_order() -> None:
    assert canonical_json({"b": 1, "a": [1, 2]}) == canonical_json({"a": [1, 2], "b": 1})


def test_put_get_missing_roundtrip(tmp_path) -> None:
    path = tmp_path / "sub" / "store.sqlite"
    with ResultStore(path) as store:
        store.put(key(0), {"success": True, "games": 12}, 0.5, "1.0")
        store.put(key(1), {"success": False, "games": 99}, 0.25, "1.0")
        assert store.missing([key(0), key(2), key(1), key(3)]) == [key(2), key(3)]
    with ResultStore(path) as store:  # durable: a new connection sees the runs
        records = store.get([key(1), key(0), key(5)])
        assert [r.key for r in records] == [key(1), key(0)]
        assert records[0].metrics == {"success": False, "games": 99}
        assert records[0].config == {"a": 1}
        assert store.count() == 2


def test_a_stored_run_is_never_changed_and_other_config_is_a_different_run(tmp_path) -> None:
    with ResultStore(tmp_path / "s.sqlite") as store:
        assert store.put(key(0), {"v": 1}, 0.1, "x")
        assert not store.put(key(0), {"v": 2}, 0.1, "y")  # a second result is dropped
        assert store.put(key(0, '{"a":2}'), {"v": 3}, 0.1, "x")
        assert store.count() == 2
        (first,) = store.get([key(0)])
        assert (first.metrics, first.version) == ({"v": 1}, "x")


def test_each_put_is_committed_immediately(tmp_path) -> None:
    path = tmp_path / "s.sqlite"
    store = ResultStore(path)
    store.put(key(0), {"v": 1}, 0.1, "x")
    # another connection (as after a crash of this process) already sees the run
    other = sqlite3.connect(path)
    assert other.execute("SELECT COUNT(*) FROM runs").fetchone()[0] == 1
    other.close()
    store.close()


# ------------------------------------------------------- paths that are not stores


@pytest.mark.parametrize("kind", STORE_PROBLEMS)
def test_a_path_that_is_not_a_store_is_refused_and_left_alone(tmp_path, kind) -> None:
    path, words = not_a_store(tmp_path, kind)
    before = path.read_bytes() if path.is_file() else None
    with pytest.raises(ConfigError, match=words) as info:
        ResultStore(path)
    assert info.value.parameter == "store"
    assert (path.read_bytes() if path.is_file() else None) == before
    assert not path.with_name(path.name + "-wal").exists()


def test_an_empty_file_and_a_killed_writer_s_store_open_fine(tmp_path) -> None:
    (tmp_path / "empty.sqlite").touch()
    with ResultStore(tmp_path / "empty.sqlite") as store:
        assert store.count() == 0
    path = tmp_path / "s.sqlite"
    store = ResultStore(path)
    store.put(key(0), {"v": 1}, 0.1, "x")  # committed to the WAL, never checkpointed
    with ResultStore(path) as again:  # as after a kill -9 of the first writer
        assert again.count() == 1
    store.close()


# ------------------------------------------------------------------ write failures


def big_key(index: int) -> RunKey:
    return key(index, canonical_json({"pad": "x" * 50_000}))


@pytest.mark.parametrize(
    ("fail", "words"),
    [
        ("full", "database or disk is full"),
        ("read-only", "attempt to write a readonly database"),
    ],
)
def test_a_failed_write_is_one_error_and_keeps_what_was_stored(
    tmp_path, monkeypatch, fail, words
) -> None:
    path = tmp_path / "s.sqlite"
    with ResultStore(path) as store:
        store.put(key(0), {"v": 1}, 0.1, "x")
    if fail == "full":
        fill_the_disk(monkeypatch)
    with ResultStore(path) as store:
        if fail == "read-only":
            store._conn.execute("PRAGMA query_only = 1")
        with pytest.raises(StoreWriteError, match=words) as info:
            store.put(big_key(1), {"v": 2}, 0.1, "x")
        assert info.value.parameter == "store"
        assert "the runs stored before are intact" in info.value.message
        assert "\n" not in info.value.message
    monkeypatch.undo()
    with ResultStore(path) as store:
        assert [(r.key, r.metrics) for r in store.records()] == [(key(0), {"v": 1})]
        store.put(big_key(1), {"v": 2}, 0.1, "x")  # with room again, writes work again
        assert store.count() == 2


def test_an_empty_store_is_discarded_only_when_no_one_holds_it(tmp_path) -> None:
    """What a failed command created and left empty goes; a store another sweep has
    open, or one that holds a run, stays."""
    from cmarlcd.sweeps.store import discard_if_empty

    unused = tmp_path / "unused.sqlite"
    ResultStore(unused).close()
    discard_if_empty(unused)
    assert not unused.exists() and not list(tmp_path.glob("unused.sqlite-*"))
    shared = tmp_path / "shared.sqlite"
    with ResultStore(shared):  # another sweep has it open, nothing stored yet
        discard_if_empty(shared)
        assert shared.exists()
    full = tmp_path / "full.sqlite"
    with ResultStore(full) as store:
        store.put(RunKey("e", "a", "{}", 0, 0), {"v": 1}, 0.0, "x")
    discard_if_empty(full)
    assert full.exists()


READ_AND_CLOSE = (
    "import sqlite3, sys\n"
    "c = sqlite3.connect(sys.argv[1])\n"
    "print(c.execute('SELECT COUNT(*) FROM runs').fetchone()[0])\n"
    "c.close()\n"
)


def _count_from_another_process(path) -> int:
    """What another process reads in the store (its connection closed afterwards, as
    ``cmarl-cd report`` does while a sweep writes)."""
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", READ_AND_CLOSE, str(path)], capture_output=True, text=True
    )
    return int(done.stdout)


def test_a_second_store_on_the_file_keeps_the_first_ones_log(tmp_path) -> None:
    """A sweep opens the store twice (its claims' heartbeat has a connection of its own).
    Opening and closing the second must leave the first's SQLite locks alone: otherwise a
    reader in another process takes itself for the last connection, deletes the
    write-ahead log under the open store, and the sweep's later runs reach no reader."""
    path = tmp_path / "store.sqlite"
    with ResultStore(path) as sweep:
        sweep.put(RunKey("e", "a", "{}", 0, 0), {"x": 1}, 1.0, "v")
        with ResultStore(path):
            pass
        assert _count_from_another_process(path) == 1
        sweep.put(RunKey("e", "a", "{}", 0, 1), {"x": 2}, 1.0, "v")
        assert (tmp_path / "store.sqlite-wal").exists()
        assert _count_from_another_process(path) == 2
