"""The results store: one row per finished run, in an embedded SQLite database.

A run is identified by ``(experiment, algorithm, config, root_seed, run_index)``;
``config`` is the run's configuration as canonical JSON (sorted keys), so two configs
that differ in any field are different experiments. Each run is committed in its own
transaction the moment it finishes (WAL journal), so a killed sweep loses at most the
runs that were in flight, and re-running the same command recomputes nothing stored.
A stored run is never changed: the first result written for a key is kept. Each row
records the package version that computed it, and a table beside records where it was
computed (:mod:`cmarlcd.provenance`: the library versions and the machine, kept once per
machine).

Sweeps that share a store share its work through *claims* (:mod:`cmarlcd.sweeps.claims`): a
sweep claims a run before computing it, and another sweep leaves a claimed run to its
owner unless the claim is stale. Storing a run removes its claim in the same transaction.

A write that fails (disk full, no permission, the file gone read-only) raises a
:class:`StoreWriteError` naming the store in one line; SQLite rolls the transaction
back, so every run stored before stays intact.

Opening a store checks it first: a path that is a directory, lies under a regular file
or cannot be written, and a file that is not a cmarl-cd store (not SQLite, truncated or
damaged, another program's database) are refused with a :class:`ConfigError` naming
``store``, before anything is written, so a wrong path never costs a computation and
a file that is not ours is never modified.
"""

from __future__ import annotations

import contextlib
import json
import os
import sqlite3
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cmarlcd.errors import ConfigError, require
from cmarlcd.runs import RunKey, RunRecord, canonical_json  # noqa: F401  (re-exported)
from cmarlcd.sweeps.claims import CLAIM_TIMEOUT, Owner, is_stale
from cmarlcd.sweeps.store_files import (  # noqa: F401  (discard_if_empty re-exported)
    _first_bytes,
    _hold_shared,
    _release,
    discard_if_empty,
)

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    experiment     TEXT    NOT NULL,
    algorithm      TEXT    NOT NULL,
    config         TEXT    NOT NULL,
    root_seed      INTEGER NOT NULL,
    run_index      INTEGER NOT NULL,
    metrics        TEXT    NOT NULL,
    wall_seconds   REAL    NOT NULL,
    version        TEXT    NOT NULL,
    finished_at    REAL    NOT NULL,
    PRIMARY KEY (experiment, algorithm, config, root_seed, run_index)
);
CREATE TABLE IF NOT EXISTS provenances (
    id             INTEGER PRIMARY KEY,
    info           TEXT    NOT NULL UNIQUE
);
CREATE TABLE IF NOT EXISTS run_provenance (
    experiment     TEXT    NOT NULL,
    algorithm      TEXT    NOT NULL,
    config         TEXT    NOT NULL,
    root_seed      INTEGER NOT NULL,
    run_index      INTEGER NOT NULL,
    provenance     INTEGER NOT NULL REFERENCES provenances (id),
    PRIMARY KEY (experiment, algorithm, config, root_seed, run_index)
);
CREATE TABLE IF NOT EXISTS claims (
    experiment     TEXT    NOT NULL,
    algorithm      TEXT    NOT NULL,
    config         TEXT    NOT NULL,
    root_seed      INTEGER NOT NULL,
    run_index      INTEGER NOT NULL,
    host           TEXT    NOT NULL,
    pid            INTEGER NOT NULL,
    started        INTEGER NOT NULL,
    heartbeat      REAL    NOT NULL,
    PRIMARY KEY (experiment, algorithm, config, root_seed, run_index)
);
"""
KEY = "experiment = ? AND algorithm = ? AND config = ? AND root_seed = ? AND run_index = ?"

#: Default location, relative to the working directory; override with ``--store``.
DEFAULT_STORE = Path("results") / "cmarl-cd.sqlite"
COLUMNS = (
    "experiment",
    "algorithm",
    "config",
    "root_seed",
    "run_index",
    "metrics",
    "wall_seconds",
    "version",
    "finished_at",
)
_SQLITE_MAGIC = b"SQLite format 3\x00"


def _existing_ancestor(path: Path, parameter: str) -> Path:
    """The nearest existing directory at or above ``path`` (a file there is an error)."""
    ancestor = path
    while not ancestor.exists():
        ancestor = ancestor.parent
    require(ancestor.is_dir(), parameter, f"{ancestor} is a file, not a directory")
    return ancestor


def check_output_directory(path: Path, parameter: str) -> None:
    """``path`` is, or can be made, a writable directory (nothing is created)."""
    ancestor = _existing_ancestor(Path(path), parameter)
    require(os.access(ancestor, os.W_OK | os.X_OK), parameter, f"cannot write in {ancestor}")


def check_store(path: Path, create: bool = True) -> None:
    """Refuse, without writing anything, a path that cannot hold a results store."""
    path = Path(path)
    require(not path.is_dir(), "store", f"{path} is a directory, not a results store")
    if not path.exists():
        _existing_ancestor(path, "store")
        require(create, "store", f"no results store at {path}; run an experiment first")
        check_output_directory(path.parent, "store")
        return
    require(os.access(path, os.R_OK), "store", f"cannot read {path}")
    if path.stat().st_size == 0:
        return  # an empty file is an empty SQLite database
    magic = _first_bytes(path, len(_SQLITE_MAGIC))
    require(magic == _SQLITE_MAGIC, "store", f"{path} is not an SQLite database")
    try:
        # immutable: read the file as it is, creating no -wal or -shm beside it
        uri = f"{path.resolve().as_uri()}?mode=ro&immutable=1"
        with contextlib.closing(sqlite3.connect(uri, uri=True)) as conn:
            check = conn.execute("PRAGMA quick_check").fetchone()[0]
            require(check == "ok", "store", f"{path} is damaged ({check})")
            tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master")}
            columns = tuple(row[1] for row in conn.execute("PRAGMA table_info(runs)"))
    except sqlite3.DatabaseError as exc:
        raise ConfigError("store", f"{path} is damaged or not a database ({exc})") from None
    require(
        not tables or columns == COLUMNS,
        "store",
        f"{path} is an SQLite database but not a cmarl-cd results store",
    )
    if create:
        require(os.access(path, os.W_OK), "store", f"cannot write {path}")
        check_output_directory(path.parent, "store")


class StoreWriteError(ConfigError):
    """Writing to the store failed (disk full, no permission); nothing stored before is
    lost."""

    def __init__(self, path: Path, exc: BaseException) -> None:
        reason = str(exc).removesuffix(".")
        super().__init__(
            "store", f"cannot write {path}: {reason}; the runs stored before are intact"
        )


Claims = tuple[list[RunKey], list[RunKey]]


def _record_provenance(conn: sqlite3.Connection, key: tuple[Any, ...], info: str) -> None:
    """Record that the run ``key`` was computed where ``info`` (a provenance's JSON text)
    says, each machine's record kept once, within the caller's transaction."""
    conn.execute("INSERT INTO provenances (info) VALUES (?) ON CONFLICT DO NOTHING", (info,))
    conn.execute(
        "INSERT INTO run_provenance SELECT ?,?,?,?,?, id FROM provenances WHERE info = ?",
        (*key, info),
    )


@dataclass(frozen=True)
class MergeCount:
    """What :meth:`ResultStore.merge` did: runs copied, runs the store already held, and
    how many of those it holds with other metrics than the source's."""

    added: int
    already: int
    differing: int


class ResultStore:
    """Read and append runs; safe to open from several processes (SQLite WAL).

    ``create=False`` opens an existing store only (for reading reports) and writes
    nothing to it.
    """

    def __init__(self, path: str | Path = DEFAULT_STORE, create: bool = True) -> None:
        self.path = Path(path)
        self._lock: tuple[int, int] | None = None
        check_store(self.path, create)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._lock = _hold_shared(self.path) if create or self.path.exists() else None
            # autocommit: each write below is one explicit transaction
            self._conn = sqlite3.connect(self.path, timeout=60.0, isolation_level=None)
            self._conn.execute("PRAGMA synchronous=NORMAL")
            if create:
                self._conn.execute("PRAGMA journal_mode=WAL")  # kept in the file
                with self._writing() as conn:
                    for statement in filter(str.strip, SCHEMA.split(";")):
                        conn.execute(statement)
            else:
                self._read_only_schema()
        except ConfigError:
            self._let_go()
            raise
        except (OSError, sqlite3.Error) as exc:
            self._let_go()
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
            raise ConfigError("store", f"cannot open {self.path} ({reason})") from None

    def _read_only_schema(self) -> None:
        """A store opened for reading is left as it is on disk (a store committed to a
        repository stays unchanged by a report): the tables an older version did not
        write are made empty in this connection's temporary schema instead."""
        listed = self._conn.execute("SELECT name FROM sqlite_master WHERE type='table'")
        tables = {row[0] for row in listed}
        for statement in filter(str.strip, SCHEMA.split(";")):
            name = statement.split("EXISTS", 1)[1].split("(", 1)[0].strip()
            if name not in tables:
                self._conn.execute(statement.replace("CREATE TABLE", "CREATE TEMP TABLE", 1))

    def close(self) -> None:
        self._let_go()

    def _let_go(self) -> None:
        """Close the connection, then the shared descriptor if it was the last store of
        this process on the file (:data:`_HELD`)."""
        conn = getattr(self, "_conn", None)
        if conn is not None:
            conn.close()
            self._conn = None  # type: ignore[assignment]
        if self._lock is not None:
            _release(self._lock)
            self._lock = None

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextlib.contextmanager
    def _writing(self) -> Iterator[sqlite3.Connection]:
        """One write transaction, taken at once (``BEGIN IMMEDIATE``: no other writer can
        slip in between its reads and its writes); a failure rolls it back."""
        try:
            self._conn.execute("BEGIN IMMEDIATE")
            yield self._conn
            self._conn.execute("COMMIT")
        except BaseException as exc:
            if self._conn.in_transaction:  # SQLite may have rolled back already
                with contextlib.suppress(sqlite3.Error):
                    self._conn.execute("ROLLBACK")
            if isinstance(exc, sqlite3.OperationalError):
                raise StoreWriteError(self.path, exc) from None
            raise

    def put(
        self,
        key: RunKey,
        metrics: Mapping[str, Any],
        wall_seconds: float,
        version: str,
        provenance: Mapping[str, Any] | None = None,
    ) -> bool:
        """Commit one finished run (and where it was computed,
        :mod:`cmarlcd.provenance`) and drop its claim, atomically. Returns False, storing
        nothing, when the run is already stored (the first result is kept)."""
        row = (
            *key.values(),
            json.dumps(dict(metrics), sort_keys=True),
            float(wall_seconds),
            version,
            time.time(),
        )
        with self._writing() as conn:
            added = conn.execute(
                "INSERT INTO runs VALUES (?,?,?,?,?,?,?,?,?) ON CONFLICT DO NOTHING", row
            ).rowcount
            if added and provenance is not None:
                _record_provenance(conn, key.values(), json.dumps(dict(provenance), sort_keys=True))
            conn.execute(f"DELETE FROM claims WHERE {KEY}", key.values())
        return added == 1

    def provenances(self) -> list[tuple[dict[str, Any] | None, int]]:
        """Where the stored runs were computed: each provenance with its number of runs,
        most runs first (None: runs stored before provenance was recorded)."""
        rows = self._conn.execute(
            "SELECT p.info, COUNT(*) FROM runs r LEFT JOIN run_provenance rp USING "
            "(experiment, algorithm, config, root_seed, run_index) "
            "LEFT JOIN provenances p ON p.id = rp.provenance GROUP BY p.info "
            "ORDER BY COUNT(*) DESC, p.info"
        )
        return [(None if info is None else json.loads(info), int(n)) for info, n in rows]

    # ---------------------------------------------------------------- claims

    def claim(self, keys: Iterable[RunKey], owner: Owner, timeout: float = CLAIM_TIMEOUT) -> Claims:
        """Claim for ``owner`` every key that is neither stored nor claimed by another
        live owner (stale claims are taken over). Returns (claimed, held by others); keys
        already stored are in neither."""
        mine: list[RunKey] = []
        theirs: list[RunKey] = []
        now = time.time()
        with self._writing() as conn:
            for key in keys:
                if conn.execute(f"SELECT 1 FROM runs WHERE {KEY}", key.values()).fetchone():
                    continue
                held = conn.execute(
                    f"SELECT host, pid, started, heartbeat FROM claims WHERE {KEY}", key.values()
                ).fetchone()
                if held is not None:
                    other = Owner(*held[:3])
                    if other != owner and not is_stale(other, held[3], now, timeout):
                        theirs.append(key)
                        continue
                conn.execute(
                    "INSERT OR REPLACE INTO claims VALUES (?,?,?,?,?,?,?,?,?)",
                    (*key.values(), owner.host, owner.pid, owner.started, now),
                )
                mine.append(key)
        return mine, theirs

    def heartbeat(self, owner: Owner) -> None:
        """Refresh the heartbeat of every claim ``owner`` holds."""
        with self._writing() as conn:
            conn.execute(
                "UPDATE claims SET heartbeat = ? WHERE host = ? AND pid = ? AND started = ?",
                (time.time(), owner.host, owner.pid, owner.started),
            )

    def release(self, owner: Owner) -> None:
        """Drop every claim ``owner`` still holds (its unfinished runs are free again)."""
        with self._writing() as conn:
            conn.execute(
                "DELETE FROM claims WHERE host = ? AND pid = ? AND started = ?",
                (owner.host, owner.pid, owner.started),
            )

    def claims(self) -> list[tuple[RunKey, Owner, float]]:
        """Every claim: its run, owner and last heartbeat."""
        rows = self._conn.execute("SELECT * FROM claims").fetchall()
        return [(RunKey(*row[:5]), Owner(*row[5:8]), float(row[8])) for row in rows]

    # ----------------------------------------------------------------- reads

    def stored_keys(self, experiment: str) -> set[RunKey]:
        """Keys of every stored run of ``experiment``."""
        cur = self._conn.execute(
            "SELECT experiment, algorithm, config, root_seed, run_index FROM runs "
            "WHERE experiment = ?",
            (experiment,),
        )
        return {RunKey(*row) for row in cur}

    def missing(self, keys: Iterable[RunKey]) -> list[RunKey]:
        """The keys among ``keys`` that are not stored yet, in the given order."""
        keys = list(keys)
        stored: set[RunKey] = set()
        for experiment in {k.experiment for k in keys}:
            stored |= self.stored_keys(experiment)
        return [k for k in keys if k not in stored]

    def records(self, experiment: str | None = None) -> Iterator[RunRecord]:
        """Stored runs, optionally of one experiment, in key order."""
        query = (
            "SELECT experiment, algorithm, config, root_seed, run_index, metrics, wall_seconds,"
            " version, finished_at FROM runs"
        )
        args: tuple[Any, ...] = ()
        if experiment is not None:
            query += " WHERE experiment = ?"
            args = (experiment,)
        query += " ORDER BY experiment, algorithm, config, root_seed, run_index"
        for row in self._conn.execute(query, args):
            metrics, seconds, version, finished = json.loads(row[5]), float(row[6]), row[7], row[8]
            yield RunRecord(RunKey(*row[:5]), metrics, seconds, version, float(finished))

    def get(self, keys: Iterable[RunKey]) -> list[RunRecord]:
        """The stored records of ``keys`` (missing keys are skipped), in the given order."""
        wanted = list(keys)
        found = {}
        for experiment in {k.experiment for k in wanted}:
            for rec in self.records(experiment):
                found[rec.key] = rec
        return [found[k] for k in wanted if k in found]

    def count(self) -> int:
        return int(self._conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0])

    # ----------------------------------------------------------------- merge

    def _rows_with_provenance(self) -> list[tuple[Any, ...]]:
        """Every stored run as its row (:data:`COLUMNS`) and where it was computed (the
        provenance's JSON text, None where the store has none)."""
        query = (
            f"SELECT {', '.join('r.' + c for c in COLUMNS)}, p.info FROM runs r "
            "LEFT JOIN run_provenance rp USING (experiment, algorithm, config, root_seed, "
            "run_index) LEFT JOIN provenances p ON p.id = rp.provenance"
        )
        return self._conn.execute(query).fetchall()

    def merge(self, source: ResultStore) -> MergeCount:
        """Copy into this store every run of ``source`` it does not hold, as ``source``
        stored it (metrics, wall time, version, finish time, where it was computed), in
        one transaction: a store computed on another machine, or by another command
        under the same settings, joins this one as if its runs had been computed here.
        A run both hold stays as this store has it (a stored run is never changed);
        those whose metrics differ are counted. ``source`` is only read."""
        require(
            source.path.resolve() != self.path.resolve(),
            "store",
            f"{source.path} is the store itself; name another store to merge into it",
        )
        rows = source._rows_with_provenance()
        added = differing = 0
        with self._writing() as conn:
            for row in rows:
                key, metrics, info = row[:5], row[5], row[-1]
                if conn.execute("INSERT INTO runs VALUES (?,?,?,?,?,?,?,?,?) ON CONFLICT DO "
                                "NOTHING", row[:-1]).rowcount:  # fmt: skip
                    added += 1
                    conn.execute(f"DELETE FROM claims WHERE {KEY}", key)
                    if info is not None:
                        _record_provenance(conn, key, info)
                    continue
                (kept,) = conn.execute(f"SELECT metrics FROM runs WHERE {KEY}", key).fetchone()
                differing += json.loads(kept) != json.loads(metrics)
        return MergeCount(added=added, already=len(rows) - added, differing=differing)
