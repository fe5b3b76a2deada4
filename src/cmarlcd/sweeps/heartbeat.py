"""The thread that keeps a sweep's claims fresh in its store
(:mod:`cmarlcd.sweeps.claims`)."""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path

from cmarlcd.sweeps.claims import HEARTBEAT_SECONDS, Owner
from cmarlcd.sweeps.store import ResultStore, StoreWriteError


class Heartbeat:
    """A thread that refreshes ``owner``'s claims every :data:`HEARTBEAT_SECONDS`, on a
    connection of its own."""

    def __init__(self, path: Path, owner: Owner) -> None:
        self.path, self.owner = path, owner
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._beat, name="claim-heartbeat", daemon=True)

    def __enter__(self) -> Heartbeat:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()

    def _beat(self) -> None:
        with contextlib.suppress(Exception), ResultStore(self.path) as store:
            while not self.stop.wait(HEARTBEAT_SECONDS):
                with contextlib.suppress(StoreWriteError):
                    store.heartbeat(self.owner)
