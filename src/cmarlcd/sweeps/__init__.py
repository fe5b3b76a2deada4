"""Sweeps: many runs computed once, durably. The results store (:mod:`~.store`, one
SQLite file, a run's first result kept), the claims that let sweeps share a store
(:mod:`~.claims`), the runner that hands runs out and stores each as it finishes
(:mod:`~.runner`), and where runs are computed (:mod:`~.backends`: this process, local
worker processes, a Ray cluster).

Above the experiments (the runner finds each run's experiment by name) and below the
reports and the command line.
"""

from cmarlcd.sweeps.runner import SweepObserver, SweepResult, default_workers, run_sweep
from cmarlcd.sweeps.store import DEFAULT_STORE, ResultStore, RunKey, RunRecord

__all__ = [
    "DEFAULT_STORE",
    "ResultStore",
    "RunKey",
    "RunRecord",
    "SweepObserver",
    "SweepResult",
    "default_workers",
    "run_sweep",
]
