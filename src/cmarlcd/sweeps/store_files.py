"""The file under an open results store (:mod:`cmarlcd.sweeps.store`): one descriptor per
file shared by every store of the process, holding a shared ``flock`` while any is open,
and the removal of a store a command created and could not fill."""

from __future__ import annotations

import contextlib
import os
import sqlite3
import threading
from pathlib import Path

try:
    import fcntl
except ImportError:  # no flock (Windows): stores are never discarded
    fcntl = None  # type: ignore[assignment]


#: The descriptors this process holds on open stores' files, by (device, inode): the
#: descriptor and how many open :class:`ResultStore` objects share it. Closing *any*
#: descriptor of a file drops every POSIX lock this process holds on it, SQLite's
#: included; with SQLite's locks gone, another process that closes its connection takes
#: itself for the last one and deletes the write-ahead log under the open store (its
#: later writes then reach no reader). So while a store is open here, its file is never
#: opened and closed again by hand: every store of the process shares one descriptor,
#: closed with the last of them, after their connections.
_HELD: dict[tuple[int, int], list[int]] = {}
_HELD_LOCK = threading.Lock()


def _first_bytes(path: Path, count: int) -> bytes:
    """The first ``count`` bytes of ``path``, read through the descriptor this process
    holds on it if it holds one (see :data:`_HELD`)."""
    with _HELD_LOCK:
        try:
            stat = path.stat()
            held = _HELD.get((stat.st_dev, stat.st_ino))
        except FileNotFoundError:
            held = None
        if held is not None:
            return os.pread(held[0], count, 0)
    with path.open("rb") as file:
        return file.read(count)


def _hold_shared(path: Path) -> tuple[int, int] | None:
    """Hold a shared ``flock`` on ``path`` while a :class:`ResultStore` is open (so that
    :func:`discard_if_empty` never removes a store in use), on the descriptor every
    store of this process on that file shares (:data:`_HELD`); its key, or None where
    the system has no ``flock``. The lock is taken again if the file was replaced
    meanwhile (removed and created anew by another process)."""
    if fcntl is None:
        return None
    with _HELD_LOCK:
        with contextlib.suppress(FileNotFoundError):
            stat = path.stat()
            held = _HELD.get((stat.st_dev, stat.st_ino))
            if held is not None:
                held[1] += 1
                return (stat.st_dev, stat.st_ino)
        while True:
            flags = os.O_RDONLY if path.exists() else os.O_RDWR | os.O_CREAT
            fd = os.open(path, flags, 0o644)
            fcntl.flock(fd, fcntl.LOCK_SH)
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                opened = os.fstat(fd)
                key = (opened.st_dev, opened.st_ino)
                _HELD[key] = [fd, 1]
                return key
            os.close(fd)  # a file no store of this process has open


def _release(key: tuple[int, int]) -> None:
    """One store of the process is closed (its connection first): the shared descriptor
    goes with the last one."""
    with _HELD_LOCK:
        held = _HELD[key]
        held[1] -= 1
        if held[1] == 0:
            del _HELD[key]
            os.close(held[0])


def discard_if_empty(path: Path) -> None:
    """Remove the store at ``path`` (and SQLite's side files) if it holds no run and no
    one else has it open: what a command created and then could not fill (a cluster it
    could not reach) goes away, and a store another sweep has just opened stays."""
    if fcntl is None or not path.is_file():
        return
    fd = os.open(path, os.O_RDONLY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # no open store holds it
        except OSError:
            return
        try:
            with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as conn:
                empty = conn.execute("SELECT COUNT(*) FROM runs").fetchone()[0] == 0
        except sqlite3.Error:  # not ours to judge: leave it
            return
        if empty:
            for extra in ("", "-wal", "-shm", "-journal"):
                path.with_name(path.name + extra).unlink(missing_ok=True)
    finally:
        os.close(fd)
