"""One local worker process of :class:`~.local.ProcessBackend`: it computes the tasks its
sweep sends over a pipe, one at a time, and sends back their progress and outcomes.

The worker starts from the fork server (or fresh, where the system has none), never from
a fork of the sweep's threads; it knows the plug-ins the sweep registered
(:mod:`cmarlcd.plugins`) or says at once which it lacks. It leaves Ctrl-C to the sweep
(which stops it), and ends as soon as the sweep's process is gone (:func:`exit_with_parent`).

Messages, worker to sweep: ``("ready", None | why_not)``, ``("progress", tag, amount,
seconds)`` (at most every 0.1 s a task), ``("done", tag, outcomes, failure)``; sweep to
worker: ``(tag, task)``, or ``None`` to end.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
from multiprocessing.connection import Connection, wait
from typing import Any

from cmarlcd.experiments import get_experiment
from cmarlcd.plugins import Registrations, missing_message
from cmarlcd.sweeps.backends.tasks import Failure, Task, run_reporting

#: How often a worker checks that its parent is still alive, in seconds (where the
#: operating system cannot tell it, as Linux's parent-death signal does).
PARENT_CHECK_SECONDS = 0.5


def serve(
    conn: Connection, device: str, threads: int, registrations: Registrations, warm: list[str]
) -> None:
    """Compute what the sweep at the other end of ``conn`` sends until it sends ``None``
    or goes away: deep learners on ``device`` with ``threads`` threads, the plug-ins of
    ``registrations`` imported and the kernels of the experiments ``warm`` loaded first."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the sweep's to handle
    exit_with_parent()
    os.environ["OMP_NUM_THREADS"] = str(threads)
    if "torch" in sys.modules:  # preloaded by the fork server
        sys.modules["torch"].set_num_threads(threads)
    missing = missing_message(registrations)
    if missing is None:
        for name in warm:  # compiled already where the fork server warmed them up
            get_experiment(name).warm_up()
    conn.send(("ready", missing))
    if missing is not None:
        return
    with contextlib.suppress(EOFError, OSError):  # the sweep went away
        while (message := conn.recv()) is not None:
            tag, task = message
            _send_done(conn, tag, task, run_reporting(tag, task, _sender(conn), device))


def _sender(conn: Connection) -> Any:
    return lambda item: conn.send(("progress", *item))


def _send_done(conn: Connection, tag: int, task: Task, finished: tuple) -> None:
    """Send a task's outcomes; outcomes that cannot be pickled fail the task instead."""
    try:
        conn.send(("done", *finished))
    except (TypeError, AttributeError, ValueError) as exc:  # pickling errors
        runs = [spec for batch in task for spec in batch]
        conn.send(("done", tag, [], Failure.of(runs, exc, keep=False)))


def exit_with_parent() -> None:
    """End this worker as soon as its parent is gone: Linux's parent-death signal (its
    parent, the fork server, ends with the sweep's process: :mod:`~.preload`), and a
    thread that watches the sweep's process (elsewhere, or as a second line; it runs
    between compiled calls)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL)
    parent = multiprocessing.parent_process()
    sentinel = getattr(parent, "sentinel", None)
    if sentinel is None:
        return
    if wait([sentinel], 0):  # the sweep died before the signal was armed
        os._exit(1)

    def watch() -> None:
        while not wait([sentinel], PARENT_CHECK_SECONDS):
            pass
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()
