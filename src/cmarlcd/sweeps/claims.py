"""Who is computing a run: the owner of a claim, and whether that owner is still alive.

Several sweeps may run on one results store at once (two terminals, two machines on a
shared disk, a sweep resumed while an old one still runs). Before computing a run a
sweep *claims* it in the store; another sweep that finds the claim waits for the run
instead of computing it again. A claim is *stale*, and may be taken over, when its owner
is gone:

- on the same host, at once: the owner's process (pid and start time, so a reused pid
  does not count) no longer exists, as after ``kill -9``;
- from another host, which cannot see the owner's processes: when its heartbeat is older
  than the claim timeout (the owner refreshes it every :data:`HEARTBEAT_SECONDS`).
"""

from __future__ import annotations

import os
import socket
from dataclasses import dataclass

#: How often a sweep refreshes the heartbeat of its claims, in seconds.
HEARTBEAT_SECONDS = 5.0
#: [choice] A claim whose heartbeat is older than this (seconds) is stale, whatever host
#: made it. Twelve missed heartbeats: long enough for a busy disk, short enough that a
#: sweep on another host takes over a dead one's runs within a minute.
CLAIM_TIMEOUT = 60.0


def _start_ticks(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot), or None if there is no such
    process; 0 where the system does not tell (the pid alone then identifies it)."""
    if not os.path.isdir("/proc/self"):  # not Linux: the pid alone identifies it
        return 0 if _pid_exists(pid) else None
    try:
        with open(f"/proc/{pid}/stat", "rb") as file:
            stat = file.read()
    except OSError:
        return None
    # the command name, field 2, is in parentheses and may hold spaces
    return int(stat[stat.rindex(b")") + 2 :].split()[19])


def _pid_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        return True
    return True


@dataclass(frozen=True)
class Owner:
    """A process that claims runs: its host, pid and start time."""

    host: str
    pid: int
    started: int

    @classmethod
    def current(cls) -> Owner:
        """This process."""
        pid = os.getpid()
        return cls(socket.gethostname(), pid, _start_ticks(pid) or 0)

    def alive(self) -> bool | None:
        """Whether the owner still runs; None when that cannot be seen from here (another
        host)."""
        if self.host != socket.gethostname():
            return None
        started = _start_ticks(self.pid)
        return started is not None and started == self.started


def is_stale(owner: Owner, heartbeat: float, now: float, timeout: float = CLAIM_TIMEOUT) -> bool:
    """Whether a claim made by ``owner``, last refreshed at ``heartbeat``, may be taken
    over at time ``now``."""
    return owner.alive() is False or now - heartbeat > timeout
