"""Merging results stores: what a merged store holds, what it keeps, what it refuses."""

from __future__ import annotations

import hashlib

import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.sweeps.claims import Owner
from cmarlcd.sweeps.store import MergeCount, ResultStore, RunKey

WHERE = {"machine": "elsewhere", "cores": 16}


def key(index: int, seed: int = 0) -> RunKey:
    return RunKey("exp", "alg", '{"a":1}', seed, index)


def digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_merged_store_holds_every_run_as_its_source_stored_it(tmp_path) -> None:
    source, into = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    with ResultStore(source) as a:
        a.put(key(0), {"v": 1.5}, 12.25, "0.6.0", provenance=WHERE)
        a.put(key(1), {"v": 2.5}, 3.0, "0.5.0")  # stored without a provenance
        written = {r.key: r for r in a.records()}
    with ResultStore(into) as b:
        b.put(key(0, seed=7), {"v": 9.0}, 1.0, "0.7.0")
    before = digest(source)
    with ResultStore(into) as b, ResultStore(source, create=False) as a:
        assert b.merge(a) == MergeCount(added=2, already=0, differing=0)
    assert digest(source) == before  # the source is only read
    with ResultStore(into, create=False) as b:
        merged = {r.key: r for r in b.records()}
        assert set(merged) == {key(0), key(1), key(0, seed=7)}
        for k, record in written.items():  # metrics, wall time, version, finish time
            assert merged[k] == record
        assert sorted(b.provenances(), key=str) == sorted([(None, 2), (WHERE, 1)], key=str)


def test_a_run_both_hold_stays_as_the_store_has_it_and_a_difference_is_counted(tmp_path) -> None:
    with ResultStore(tmp_path / "a.sqlite") as a:
        a.put(key(0), {"v": 1.0}, 1.0, "x")  # the same result
        a.put(key(1), {"v": 2.0}, 1.0, "x")  # another result for a stored run
        a.put(key(2), {"v": 3.0}, 1.0, "x")
    with ResultStore(tmp_path / "b.sqlite") as b, ResultStore(tmp_path / "a.sqlite") as a:
        b.put(key(0), {"v": 1.0}, 5.0, "y")
        b.put(key(1), {"v": -2.0}, 5.0, "y")
        assert b.merge(a) == MergeCount(added=1, already=2, differing=1)
        kept = {r.key: r.metrics for r in b.records()}
        assert kept == {key(0): {"v": 1.0}, key(1): {"v": -2.0}, key(2): {"v": 3.0}}
        assert b.merge(a) == MergeCount(added=0, already=3, differing=1)  # nothing twice


def test_a_merged_run_frees_its_claim(tmp_path) -> None:
    owner = Owner("host", 123, 1)
    with ResultStore(tmp_path / "a.sqlite") as a:
        a.put(key(0), {"v": 1.0}, 1.0, "x")
    with ResultStore(tmp_path / "b.sqlite") as b, ResultStore(tmp_path / "a.sqlite") as a:
        assert b.claim([key(0), key(1)], owner) == ([key(0), key(1)], [])
        b.merge(a)
        assert [k for k, _, _ in b.claims()] == [key(1)]


def test_a_store_is_not_merged_into_itself(tmp_path) -> None:
    path = tmp_path / "a.sqlite"
    with ResultStore(path) as a:
        a.put(key(0), {"v": 1.0}, 1.0, "x")
        same = ResultStore(tmp_path / "." / "a.sqlite", create=False)
        with same, pytest.raises(ConfigError, match="the store itself"):
            a.merge(same)
        assert a.count() == 1
