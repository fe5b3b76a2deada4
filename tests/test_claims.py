"""Sharing a store: claims, their owners, and sweeps that split the work between them."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cmarlcd.sweeps.claims import Owner, is_stale
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore
from tests.sleepy_sweep import specs as sleepy_specs

SCRIPT = Path(__file__).with_name("sleepy_sweep.py")


def dead_owner() -> Owner:
    """An owner on this host whose process has exited."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return Owner(Owner.current().host, child.pid, 1)


def test_an_owner_is_alive_while_its_process_runs() -> None:
    me = Owner.current()
    assert me.alive() is True
    assert dead_owner().alive() is False
    assert Owner(me.host, me.pid, me.started + 1).alive() is False  # a reused pid
    assert Owner("another-host", me.pid, me.started).alive() is None


def test_staleness_by_death_here_or_silence_elsewhere() -> None:
    now = 1000.0
    assert not is_stale(Owner.current(), now - 500, now, timeout=600)
    assert is_stale(dead_owner(), now, now, timeout=600)  # dead: at once
    far = Owner("another-host", 1, 1)
    assert not is_stale(far, now - 30, now, timeout=60)
    assert is_stale(far, now - 61, now, timeout=60)


def test_claims_go_to_the_first_and_storing_drops_them(tmp_path) -> None:
    keys = [s.key for s in sleepy_specs(3, 0.0)]
    me, other = Owner.current(), Owner("another-host", 7, 7)
    with ResultStore(tmp_path / "s.sqlite") as store:
        assert store.claim(keys[:2], other) == (keys[:2], [])
        assert store.claim(keys, me) == ([keys[2]], keys[:2])
        store.put(keys[2], {"v": 1}, 0.0, "x")
        assert store.claim(keys[2:], other) == ([], [])  # stored: nobody's to claim
        assert {key for key, _, _ in store.claims()} == set(keys[:2])
        store.release(other)
        assert store.claims() == []


def test_concurrent_sweeps_split_the_work_and_store_each_run_once(tmp_path) -> None:
    store, go, runs = tmp_path / "s.sqlite", tmp_path / "go", 12
    ResultStore(store).close()
    command = [sys.executable, str(SCRIPT), str(store), str(runs), "0.15", str(go)]
    sweeps = [subprocess.Popen(command, stdout=subprocess.PIPE, text=True) for _ in range(2)]
    deadline = time.monotonic() + 120  # however loaded the machine: both ready, then go
    while len(list(tmp_path.glob("go.ready.*"))) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    go.touch()
    tallies = [json.loads(p.communicate(timeout=120)[0]) for p in sweeps]
    assert all(p.returncode == 0 for p in sweeps)
    computed = [t["computed"] for t in tallies]
    assert sum(computed) == runs and min(computed) >= 2, tallies  # both worked
    for tally in tallies:  # each saw every run: its own, the other's, none twice
        assert tally["computed"] + tally["shared"] + tally["reused"] == runs
    with ResultStore(store) as db:
        assert db.count() == runs and db.claims() == []


def test_a_claim_left_by_a_killed_sweep_is_taken_over(tmp_path) -> None:
    todo = sleepy_specs(4, 0.0)
    with ResultStore(tmp_path / "s.sqlite") as store:
        store.claim([s.key for s in todo[:2]], dead_owner())
        done = run_sweep(todo, store, workers=1)
        assert (done.computed, done.shared) == (4, 0)
        assert store.count() == 4 and store.claims() == []


def test_a_silent_claim_from_another_host_is_taken_over_after_the_timeout(tmp_path) -> None:
    todo = sleepy_specs(2, 0.0)
    with ResultStore(tmp_path / "s.sqlite") as store:
        store.claim([todo[0].key], Owner("another-host", 1, 1))
        time.sleep(0.3)
        done = run_sweep(todo, store, workers=1, claim_timeout=0.2)
        assert done.computed == 2 and store.count() == 2


def test_a_live_claim_is_waited_for_not_recomputed(tmp_path) -> None:
    todo = sleepy_specs(3, 0.0)
    path = tmp_path / "s.sqlite"
    other = Owner("another-host", 1, 1)
    with ResultStore(path) as store:
        store.claim([todo[0].key], other)

    def other_sweep_finishes() -> None:
        time.sleep(1.5)
        with ResultStore(path) as theirs:
            theirs.put(todo[0].key, {"value": -1.0}, 0.0, "theirs")

    finisher = threading.Thread(target=other_sweep_finishes)
    finisher.start()
    with ResultStore(path) as store:
        done = run_sweep(todo, store, workers=1)
        finisher.join()
        assert (done.computed, done.shared) == (2, 1)
        assert store.get([todo[0].key])[0].metrics == {"value": -1.0}  # theirs, kept


@pytest.mark.parametrize("workers", [1, 2])
def test_a_sweep_leaves_no_claim_behind(tmp_path, workers: int) -> None:
    with ResultStore(tmp_path / "s.sqlite") as store:
        run_sweep(sleepy_specs(4, 0.0), store, workers=workers)
        assert store.claims() == []
