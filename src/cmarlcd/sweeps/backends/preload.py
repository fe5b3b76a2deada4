"""What the fork server that starts a sweep's workers does once, when it starts.

:class:`~.local.ProcessBackend` starts :mod:`multiprocessing`'s fork server with the
package's modules preloaded (those the sweep's process has imported, torch with them
where the sweep trains deep learners) and this module last: it ties the server's life
to the sweep's process (Linux's parent-death signal, armed where the server was started
from the sweep's main thread: :data:`PARENT_ENV`), and compiles (or loads from numba's
cache) the kernels of the experiments named in :data:`WARM_UP_ENV`. Every worker is then
a fork of this one quiet, single-threaded process, and starts with its kernels ready.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys

#: The sweep's process id, where the server should end with it.
PARENT_ENV = "CMARLCD_FORKSERVER_PARENT"
#: The experiments whose kernels the server compiles, comma-separated.
WARM_UP_ENV = "CMARLCD_WARM_UP"


def _end_with_parent() -> None:
    parent = os.environ.pop(PARENT_ENV, "")
    if not parent or not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError):
        pr_set_pdeathsig = 1
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, signal.SIGKILL)
    if os.getppid() != int(parent):  # the sweep died before the signal was armed
        os._exit(0)


def _warm_up() -> None:
    names = [name for name in os.environ.pop(WARM_UP_ENV, "").split(",") if name]
    for name in names:
        try:  # a plug-in's experiment is not known here; its workers warm it up
            from cmarlcd.experiments import get_experiment

            get_experiment(name).warm_up()
        except Exception:  # the server must start whatever happens
            pass


_end_with_parent()
_warm_up()
