"""How a sweep ended: its tally (:class:`SweepResult`), and the two ways it stops early,
each one line that says how many runs are stored and how to resume: Ctrl-C
(:class:`SweepInterrupted`) and a run that failed (:class:`RunFailed`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.backends.tasks import Failure


@dataclass
class SweepResult:
    """How a sweep went: runs computed here, found in the store at the start, and stored
    meanwhile by another sweep on the same store."""

    total: int
    computed: int = 0
    reused: int = 0
    shared: int = 0
    duplicates: int = 0
    """Runs computed here that another sweep had stored first (its result was kept)."""
    wall_seconds: float = 0.0
    interrupted: bool = False
    run_seconds: list[float] = field(default_factory=list)


class SweepInterrupted(RuntimeError):
    """The sweep was stopped (Ctrl-C); finished runs are in the store."""

    def __init__(self, result: SweepResult) -> None:
        self.result = result
        super().__init__(f"interrupted: {_tally(result)}")


class RunFailed(RuntimeError):
    """A run raised, or the worker process computing it died: the sweep ended there.

    The message is one line: the run (experiment, algorithm, run index, root seed and
    config), its error, and how many runs are stored. ``failure`` holds the traceback
    (:attr:`~cmarlcd.sweeps.backends.tasks.Failure.details`); the run's own exception is
    the ``__cause__`` where it survived the trip from its worker."""

    def __init__(self, result: SweepResult, failure: Failure) -> None:
        self.result, self.failure = result, failure
        what = f"{describe_runs(failure.runs)} failed: " if failure.runs else ""
        super().__init__(f"{what}{failure.error}; {_tally(result)}")


def _tally(result: SweepResult) -> str:
    stored = result.reused + result.computed + result.shared
    return (
        f"{stored} of {result.total} runs are stored, {result.total - stored} left;"
        " run the same command again to resume"
    )


def describe_runs(runs: Sequence[RunSpec]) -> str:
    """Runs of one config in words: ``run 3 of dsn cmarl-cd (root seed 0, config {...})``."""
    first = runs[0]
    indices = sorted(spec.run_index for spec in runs)
    which = f"run {indices[0]}" if len(indices) == 1 else f"runs {', '.join(map(str, indices))}"
    return (
        f"{which} of {first.experiment} {first.algorithm} (root seed {first.root_seed},"
        f" config {first.config_json})"
    )
