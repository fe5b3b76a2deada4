"""The results store: one row per finished run, in an embedded SQLite database.

A run is identified by ``(experiment, algorithm, config, root_seed, run_index)``;
``config`` is the run's configuration as canonical JSON (sorted keys), so two configs
that differ in any field are different experiments. Each run is committed in its own
transaction the moment it finishes (WAL journal), so a killed sweep loses at most the
runs that were in flight, and re-running the same command recomputes nothing stored.
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
)
"""

#: Default location, relative to the working directory; override with ``--store``.
DEFAULT_STORE = Path("results") / "cmarl-cd.sqlite"


def canonical_json(config: Mapping[str, Any]) -> str:
    """The canonical text of a config: sorted keys, no whitespace."""
    return json.dumps(dict(config), sort_keys=True, separators=(",", ":"))


@dataclass(frozen=True)
class RunKey:
    """The identity of one run in the store."""

    experiment: str
    algorithm: str
    config: str
    root_seed: int
    run_index: int


@dataclass(frozen=True)
class RunRecord:
    """A stored run: its key, its metrics and how long it took."""

    key: RunKey
    metrics: dict[str, Any]
    wall_seconds: float

    @property
    def config(self) -> dict[str, Any]:
        return json.loads(self.key.config)


class ResultStore:
    """Read and append runs; safe to open from several processes (SQLite WAL)."""

    def __init__(self, path: str | Path = DEFAULT_STORE) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._conn = sqlite3.connect(self.path, timeout=60.0)
        self._conn.execute("PRAGMA journal_mode=WAL")
        self._conn.execute("PRAGMA synchronous=NORMAL")
        with self._conn:
            self._conn.execute(SCHEMA)

    def close(self) -> None:
        self._conn.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def put(
        self, key: RunKey, metrics: Mapping[str, Any], wall_seconds: float, version: str
    ) -> None:
        """Commit one finished run atomically (replacing a stored run with the same key)."""
        row = (
            key.experiment,
            key.algorithm,
            key.config,
            key.root_seed,
            key.run_index,
            json.dumps(dict(metrics), sort_keys=True),
            float(wall_seconds),
            version,
            time.time(),
        )
        with self._conn:
            self._conn.execute("INSERT OR REPLACE INTO runs VALUES (?,?,?,?,?,?,?,?,?)", row)

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
            "SELECT experiment, algorithm, config, root_seed, run_index, metrics, wall_seconds "
            "FROM runs"
        )
        args: tuple[Any, ...] = ()
        if experiment is not None:
            query += " WHERE experiment = ?"
            args = (experiment,)
        query += " ORDER BY experiment, algorithm, config, root_seed, run_index"
        for row in self._conn.execute(query, args):
            yield RunRecord(RunKey(*row[:5]), json.loads(row[5]), float(row[6]))

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
