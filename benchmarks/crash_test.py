"""Crash test: kill a sweep with SIGKILL at random moments, many times, and resume it.

Runs a sweep once without interruption (the reference), then again into a second store,
killing the sweep's process with SIGKILL (as an out-of-memory killer would; its workers
must exit by themselves) at a random moment ``--kills`` times: once the resumed sweep
has stored its first run, after a random part of the time the reference took from
there to its last run, so kills land between and in the middle of runs. Each time it
resumes with the same command; a resumed sweep that finishes before its kill is
checked, and a new one started. Finally it lets it finish.
It then checks that:

- every run is stored exactly once (the stores hold the same keys, and as many rows as
  the reference);
- every stored metric equals the reference's, bit for bit (timings aside);
- no claim is left in the store and the SQLite file passes ``PRAGMA integrity_check``;
- no process of a killed sweep outlives it.

Usage: python benchmarks/crash_test.py [--sweep dsn|tournament|repeated] [--kills 20]
           [--workers 2] [--seed 0] [--dir DIR]
Prints one line per attempt and ``PASS`` (exit 0) or what failed (exit 1).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import random
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from compare_stores import load  # noqa: E402

#: The sweeps to crash, as ``cmarl-cd`` arguments; deep learners join when torch is here.
SWEEPS = {
    "dsn": ["dsn", "--algorithms", "cmarl-cd,la-oca{deep}", "--episodes", "2000,4000",
            "--runs", "10", "--eval-episodes", "500", "--seed-batch", "3"],
    "tournament": ["tournament", "--algorithms", "cmarl-cd,la-oca{deep}", "--rounds", "3",
                   "--learn-episodes", "300", "--eval-episodes", "300", "--seed-batch", "3"],
    "repeated": ["repeated", "--agents", "2-6", "--actions", "2-4", "--runs", "6"],
}  # fmt: skip


def sweep_command(name: str, workers: int, store: Path, figures: Path) -> list[str]:
    deep = ",vdn" if _has_torch() else ""
    args = [a.replace("{deep}", deep) for a in SWEEPS[name]]
    return [
        sys.executable, "-m", "cmarlcd", *args, "--workers", str(workers), "--no-progress",
        "--store", str(store), "--figures", str(figures),
    ]  # fmt: skip


def _has_torch() -> bool:
    import importlib.util

    return importlib.util.find_spec("torch") is not None


def start(command: list[str]) -> subprocess.Popen:
    """The command in a process group of its own (so its workers can be checked too)."""
    return subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
    )


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def kill_when(process: subprocess.Popen, store: Path, target: int, extra: float) -> int | None:
    """SIGKILL the sweep (its parent process only, as an OOM killer would) ``extra``
    seconds after ``target`` runs are stored; the runs stored at that moment, or None if
    it finished first. Its workers must then exit by themselves."""
    while process.poll() is None and stored(store) < target:
        time.sleep(0.02)
    try:
        process.wait(timeout=extra)
        return None
    except subprocess.TimeoutExpired:
        pass
    at_kill = stored(store)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    deadline = time.monotonic() + 10
    while group_alive(process.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    if group_alive(process.pid):
        os.killpg(process.pid, signal.SIGKILL)
        raise SystemExit("FAIL: a worker outlived its killed sweep by 10 s")
    return at_kill


def timeline(process: subprocess.Popen, store: Path) -> list[float]:
    """Seconds from the start of ``process`` to the moment its store held 1, 2, ... runs
    (polled every 20 ms, until it exits)."""
    began, times = time.perf_counter(), []
    while process.poll() is None:
        count = stored(store)
        times += [time.perf_counter() - began] * (count - len(times))
        time.sleep(0.02)
    count = stored(store)
    return times + [time.perf_counter() - began] * (count - len(times))


def stored(path: Path) -> int:
    if not path.exists():
        return 0
    try:
        with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn:
            return conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
    except sqlite3.OperationalError:  # not created yet
        return 0


def check(reference: Path, crashed: Path) -> list[str]:
    """What differs between the two stores, or is wrong in the crashed one."""
    problems = []
    ref, got = load(str(reference)), load(str(crashed))
    if set(ref) != set(got):
        problems.append(f"keys differ: {len(set(ref) - set(got))} missing, "
                        f"{len(set(got) - set(ref))} extra")  # fmt: skip
    differing = [k for k in set(ref) & set(got) if ref[k] != got[k]]
    if differing:
        problems.append(f"{len(differing)} runs with different metrics, e.g. {differing[0]}")
    with sqlite3.connect(crashed) as conn:
        rows = conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0]
        claims = conn.execute("SELECT COUNT(*) FROM claims").fetchone()[0]
        integrity = conn.execute("PRAGMA integrity_check").fetchone()[0]
    if rows != len(ref):
        problems.append(f"{rows} rows stored for {len(ref)} runs")
    if claims:
        problems.append(f"{claims} claims left in the store")
    if integrity != "ok":
        problems.append(f"integrity check: {integrity}")
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", choices=sorted(SWEEPS), default="dsn")
    parser.add_argument("--kills", type=int, default=20)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0, help="seed of the kill moments")
    parser.add_argument("--dir", type=Path, default=None, help="keep the stores here")
    args = parser.parse_args(argv)
    folder = args.dir or Path(tempfile.mkdtemp(prefix="cmarl-cd-crash-"))
    folder.mkdir(parents=True, exist_ok=True)
    reference, crashed, figures = (
        folder / "reference.sqlite",
        folder / "crashed.sqlite",
        folder / "f",
    )
    for path in (reference, crashed):
        for suffix in ("", "-wal", "-shm"):
            Path(f"{path}{suffix}").unlink(missing_ok=True)

    began = time.perf_counter()
    done = start(sweep_command(args.sweep, args.workers, reference, figures))
    stored_at = timeline(done, reference)
    if done.wait() != 0:
        raise SystemExit(f"FAIL: the reference sweep failed: {done.stderr.read().decode()}")
    total = stored(reference)
    print(f"reference: {total} runs in {time.perf_counter() - began:.1f} s, "
          f"stored from {stored_at[0]:.1f} s to {stored_at[-1]:.1f} s")  # fmt: skip

    rng = random.Random(args.seed)
    kills = attempts = chain = late = 0
    failed = False
    command = sweep_command(args.sweep, args.workers, crashed, figures)
    while kills < args.kills:
        attempts += 1
        # a random moment of the computation: once the resumed sweep stores its first
        # run, a random part of the time the reference took from there to its last run
        # (so kills land between and in the middle of runs, seed batches included)
        before = stored(crashed)
        target = min(before + 1, total)
        extra = rng.uniform(0.0, max(stored_at[-1] - stored_at[target - 1], 0.05))
        at_kill = kill_when(start(command), crashed, target, extra) if before < total else None
        killed = at_kill is not None
        kills, chain, late = kills + killed, chain + killed, late + (at_kill == total)
        moment = f"killed at {at_kill}/{total} stored" if killed else "finished"
        print(f"attempt {attempts}: {moment} ({extra:.2f} s after run {target}); "
              f"{before} -> {stored(crashed)}/{total} runs stored")  # fmt: skip
        if not killed:  # a resumed sweep finished: check it, then start a new one
            failed |= report(check(reference, crashed), chain, total)
            for suffix in ("", "-wal", "-shm"):
                Path(f"{crashed}{suffix}").unlink(missing_ok=True)
            chain = 0
    last = start(command)
    if last.wait() != 0:
        raise SystemExit(f"FAIL: the final resume failed: {last.stderr.read().decode()}")
    print(f"resumed to the end: {stored(crashed)}/{total} runs stored")
    failed |= report(check(reference, crashed), chain, total)
    print(f"{'FAIL' if failed else 'PASS'}: {kills} kills in {attempts + 1} attempts "
          f"({kills - late} with runs still to compute, {late} after the last run was "
          "stored)")  # fmt: skip
    return 1 if failed else 0


def report(problems: list[str], kills: int, total: int) -> bool:
    """Print how one resumed sweep ended; True if it failed."""
    for problem in problems:
        print(f"  FAIL: {problem}")
    if not problems:
        print(f"  ok: after {kills} kills, {total} runs each stored once, as in the reference")
    return bool(problems)


if __name__ == "__main__":
    sys.exit(main())
