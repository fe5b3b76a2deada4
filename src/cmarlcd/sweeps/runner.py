"""A sweep: compute every run a store lacks, on a backend, committing each as it finishes.

The sweep's process is the store's one writer: results come back from the backend
(:mod:`cmarlcd.sweeps.backends`: in-process, local processes or Ray) and are committed one
transaction per run. Runs of one config that the experiment can batch (seeds stacked in
one model) travel together, ``seed_batch`` at a time.

**Sharing a store.** Before a batch is handed to the backend its runs are claimed in the
store (:mod:`cmarlcd.sweeps.claims`); only as many batches are handed out as the backend can
work on, so two sweeps started on one store take turns claiming and split the work. Runs
another live sweep has claimed are waited for, not recomputed; a claim whose owner died
is taken over. A heartbeat thread keeps this sweep's claims fresh.

**Progress** is reported to a :class:`SweepObserver` by *section* (a part of the sweep
the caller names, e.g. one table), in the section's one work unit (episodes, or runs for
an experiment that reports none; a named part whose experiments count in different units
becomes one section per unit) and in estimated seconds (each experiment's ``cost``), so
one view can show every section and an overall ETA. A section's reported work reaches its
total exactly when its last run is stored, and never passes it: what a task reports is
capped at the task's own work (a task Ray retries reports again), and the rest is added
when its runs are stored. Ctrl-C stops the backend and keeps every finished run.

**Failures.** A run that raises, or a worker process that dies, ends the sweep at once
with one line naming the run (:class:`RunFailed`; a bad setting found in a worker, a
:class:`~cmarlcd.errors.ConfigError`, as itself); the runs finished before it, in that
task too, are stored first, so the same command resumes from there.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cmarlcd.devices import DEFAULT_DEVICE, GPU_TASKS, resolve
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import get_experiment, settings_of
from cmarlcd.limits import check_gpu_tasks, check_seed_batch, check_workers
from cmarlcd.policies.files import keep_policy
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.backends import check_backend, default_workers, make_backend
from cmarlcd.sweeps.backends.tasks import PROVENANCE, Failure
from cmarlcd.sweeps.claims import CLAIM_TIMEOUT, Owner
from cmarlcd.sweeps.heartbeat import Heartbeat
from cmarlcd.sweeps.outcome import RunFailed, SweepInterrupted, SweepResult
from cmarlcd.sweeps.store import ResultStore, RunKey, StoreWriteError

__all__ = [
    "RunFailed",
    "SweepInterrupted",
    "SweepObserver",
    "SweepResult",
    "default_workers",
    "run_sweep",
]

#: How often a sweep asks the store about runs another sweep holds, in seconds.
WAIT_POLL_SECONDS = 1.0


@dataclass(frozen=True)
class Section:
    """One part of a sweep as a progress view shows it."""

    name: str
    runs: int
    stored_runs: int
    work: float
    stored_work: float
    unit: str
    cost: float
    """Estimated seconds of every run (``Experiment.cost``)."""
    stored_cost: float
    todo_costs: Mapping[str, float] = field(default_factory=dict)
    """Estimated seconds of the runs to compute, by kind (:func:`kind_of`)."""
    finish_costs: Mapping[str, float] = field(default_factory=dict)
    """Estimated seconds, by kind, of all the work the sweep hands out (every section's)
    up to and including this section's last task: the section ends about when that much
    is done."""


class SweepObserver:
    """Receives a sweep's progress; the default ignores it."""

    def start(self, sections: Sequence[Section]) -> None:
        """The sweep has these sections (stored runs count as done)."""

    def advance(self, section: str, work: float, cost: float, kind: str = "") -> None:
        """``work`` more units of ``section`` are done, ``cost`` estimated seconds of runs
        of ``kind`` (over the sweep, the amounts add up to each section's totals)."""

    def task_progress(self, section: str, task: int, kind: str, done: float, total: float) -> None:
        """Task ``task`` (runs of ``section``, handed out together to one worker, first
        of ``kind``) has done ``done`` of its ``total`` estimated seconds; it is handed
        out with ``done == 0`` and ends, its runs stored, with ``done == total``."""

    def run_finished(
        self, section: str, kind: str = "", cost: float = 0.0, seconds: float = math.nan
    ) -> None:
        """One more run of ``section`` is stored: a run of ``kind`` estimated at ``cost``
        seconds that took ``seconds`` to compute (NaN: another sweep computed it)."""

    def finish(self) -> None:
        """The sweep has ended (finished or interrupted)."""


class _TaskFailed(Exception):
    def __init__(self, failure: Failure) -> None:
        self.failure = failure


def work_of(spec: RunSpec) -> float:
    """The progress units of one run (the run itself, for an experiment that reports none)."""
    work = get_experiment(spec.experiment).work(settings_of(spec))
    return 1.0 if work is None else float(work)


def cost_of(spec: RunSpec) -> float:
    return float(get_experiment(spec.experiment).cost(settings_of(spec)))


def reports_work(spec: RunSpec) -> bool:
    return get_experiment(spec.experiment).work(settings_of(spec)) is not None


def run_sweep(
    specs: Sequence[RunSpec],
    store: ResultStore,
    *,
    workers: int | None = None,
    version: str = "",
    observer: SweepObserver | None = None,
    description: str = "runs",
    seed_batch: int = 1,
    backend: str = "process",
    address: str | None = None,
    section: Callable[[RunSpec], str] | None = None,
    claim_timeout: float = CLAIM_TIMEOUT,
    device: str = DEFAULT_DEVICE,
    gpu_tasks: int = GPU_TASKS,
    policies: Path | None = None,
    logs: Path | None = None,
) -> SweepResult:
    """Compute every spec not yet in ``store`` and commit each as it finishes.

    Args:
        workers: processes (``process``) or CPUs (``ray``); default all cores, or for
            Ray with an address, all CPUs of the cluster.
        section: names the progress section of a spec (default: ``description``).
        backend: ``process`` or ``ray``; ``address`` joins a running Ray cluster.
        claim_timeout: seconds after which another host's silent claim is stale.
        device: where deep learners compute (:mod:`cmarlcd.devices`; ``cpu``, ``cuda``,
            ``cuda:N``, ``auto``); a run's identity and seeds do not depend on it.
        gpu_tasks: deep tasks that share one GPU at a time (local worker processes on
            the card, or each one's share of a GPU on Ray).
        policies: where each run computed now keeps its final greedy policy
            (:mod:`cmarlcd.policies`; runs found in the store keep none).
        logs: where each run computed now writes its live curves (:mod:`cmarlcd.run_logs`).

    Runs of one config whose experiment can batch them are computed ``seed_batch`` at a
    time in one call (the results are the same as one by one).
    """
    check_not_importing()
    check_backend(backend, address)
    if workers is None and not (backend == "ray" and address):
        workers = default_workers()
    check_workers(workers)
    check_seed_batch(seed_batch)
    check_gpu_tasks(gpu_tasks)
    if backend != "ray":  # a GPU asked for where there is none: refused before anything runs
        device = resolve(device)
    named = section or (lambda _: description)
    if policies is not None or logs is not None:
        kept, logged = policies is not None, None if logs is None else str(logs)
        specs = [replace(spec, keep_policy=kept, log_dir=logged) for spec in specs]
    sections = one_unit_sections(specs, named)
    sweep = _Sweep(specs, store, version, observer or SweepObserver(), sections, policies)

    # local workers with a GPU: one more than the batches, as the GPU's lane leaves one
    # worker to the CPU's, so that as many deep batches as there are run at once
    spare = int(backend != "ray" and device != DEFAULT_DEVICE)

    def start_backend(progress: Callable[[int, float, float], None], batches: int) -> Any:
        used = workers if workers is None else min(workers, batches + spare)
        return make_backend(backend, used, progress, address, device, gpu_tasks)

    return sweep.run(seed_batch, claim_timeout, start_backend)


def check_not_importing() -> None:
    """Refuse a sweep started while this process, a worker, imports the script that
    started its own sweep: the script runs its sweep at import rather than under
    ``if __name__ == "__main__":``, and each worker would start a sweep of its own."""
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise RuntimeError(
            "a worker process, importing the script that started the sweep, was asked to "
            "start a sweep too: start it under `if __name__ == '__main__':`"
        )


def kind_of(spec: RunSpec) -> str:
    """Runs of one kind (experiment and algorithm) run at about the same pace against
    their estimated cost: a progress view calibrates each kind's estimates on its
    finished runs."""
    return f"{spec.experiment}:{spec.algorithm}"


def unit_of(spec: RunSpec) -> str:
    """What a run's progress counts: its experiment's unit, or runs if it reports none."""
    return get_experiment(spec.experiment).work_unit if reports_work(spec) else "runs"


def one_unit_sections(
    specs: Sequence[RunSpec], section: Callable[[RunSpec], str]
) -> Callable[[RunSpec], str]:
    """``section``, with a named part whose runs count in several units split into one
    section per unit (``"compare (episodes)"``), so that every bar has one unit."""
    units: dict[str, set[str]] = {}
    for spec in specs:
        units.setdefault(section(spec), set()).add(unit_of(spec))
    mixed = {name for name, found in units.items() if len(found) > 1}
    if not mixed:
        return section

    def split(spec: RunSpec) -> str:
        name = section(spec)
        return f"{name} ({unit_of(spec)})" if name in mixed else name

    return split


class _Sweep:
    """The state of one :func:`run_sweep` call."""

    def __init__(
        self,
        specs: Sequence[RunSpec],
        store: ResultStore,
        version: str,
        observer: SweepObserver,
        section: Callable[[RunSpec], str],
        policies: Path | None = None,
    ) -> None:
        self.specs, self.store, self.version = list(specs), store, version
        self.policies = policies  # where runs keep their policies (--save-policies)
        self.observer, self.section = observer, section
        self.owner = Owner.current()
        self.next_tag = 0
        self.inflight: dict[int, list[RunSpec]] = {}
        self.waiting: dict[RunKey, RunSpec] = {}

    def run(self, seed_batch: int, claim_timeout: float, backend_factory: Callable) -> SweepResult:
        missing = set(self.store.missing(s.key for s in self.specs))
        todo = sorted((s for s in self.specs if s.key in missing), key=lambda s: -cost_of(s))
        self.result = SweepResult(total=len(self.specs), reused=len(self.specs) - len(todo))
        self.batches = _batches(todo, seed_batch)
        self.claim_timeout = claim_timeout
        # connect first (a wrong Ray address fails before anything is shown); local
        # workers start with the first task, with the kernels prepared for them
        backend = backend_factory(self._progress, len(self.batches)) if todo else None
        self.observer.start(self._sections(missing))
        start = time.perf_counter()
        try:
            if backend is not None:
                backend.prepare(todo)
                self.queue = deque(self._tasks(backend.task_seconds))
                with Heartbeat(self.store.path, self.owner):
                    self._loop(backend)
        except KeyboardInterrupt:
            self.result.interrupted = True
            raise SweepInterrupted(self.result) from None
        except _TaskFailed as stop:
            self.result.interrupted = True
            error = self._ended_by(stop.failure)
            raise error from error.__cause__
        finally:
            if backend is not None:
                backend.close(cancel=bool(self.inflight) or self.result.interrupted)
            with contextlib.suppress(StoreWriteError):
                self.store.release(self.owner)
            self.result.wall_seconds = time.perf_counter() - start
            self.observer.finish()
        return self.result

    def _ended_by(self, failure: Failure) -> Exception:
        """What a failed task ends the sweep with: a Ctrl-C in its worker as the sweep's
        own, a bad setting as itself, anything else as :class:`RunFailed` (its cause the
        run's exception, where it came back)."""
        if failure.interrupted:
            return SweepInterrupted(self.result)
        if isinstance(failure.exception, ConfigError):
            return failure.exception
        error = RunFailed(self.result, failure)
        error.__cause__ = failure.exception
        return error

    def _sections(self, missing: set[RunKey]) -> list[Section]:
        grouped: dict[str, list[RunSpec]] = {}
        for spec in self.specs:
            grouped.setdefault(self.section(spec), []).append(spec)
        finish: dict[str, dict[str, float]] = {}
        queued: dict[str, float] = {}
        for batch in self.batches:  # in the order they are handed out
            for spec in batch:
                kind = kind_of(spec)
                queued[kind] = queued.get(kind, 0.0) + cost_of(spec)
            finish[self.section(batch[0])] = dict(queued)
        sections = []
        for name, specs in grouped.items():
            stored = [s for s in specs if s.key not in missing]
            todo: dict[str, float] = {}
            for spec in specs:
                if spec.key in missing:
                    todo[kind_of(spec)] = todo.get(kind_of(spec), 0.0) + cost_of(spec)
            sections.append(
                Section(
                    name,
                    len(specs),
                    len(stored),
                    sum(map(work_of, specs)),
                    sum(map(work_of, stored)),
                    get_experiment(specs[0].experiment).work_unit,
                    sum(map(cost_of, specs)),
                    sum(map(cost_of, stored)),
                    todo,
                    finish.get(name, {}),
                )
            )
        return sections

    # ------------------------------------------------------------------ the loop

    def _loop(self, backend: Any) -> None:
        self.tags: dict[int, _Tag] = {}
        next_poll = 0.0
        while self.queue or self.inflight or self.waiting:
            self._fill(backend)
            failures = []
            for tag, outcomes, failure in backend.poll(0.2 if self.inflight else WAIT_POLL_SECONDS):
                for outcome in outcomes:
                    self._commit(*outcome)
                if failure is not None:
                    failures.append(failure)
                else:
                    del self.inflight[tag]
                    self._settle(tag)
            if failures:  # every run finished before is stored
                raise _TaskFailed(failures[0])
            if self.waiting and time.monotonic() >= next_poll:
                self._check_waiting()
                next_poll = time.monotonic() + WAIT_POLL_SECONDS

    def _fill(self, backend: Any) -> None:
        """Hand out tasks in queue order while the backend has room, passing over those
        whose lane is full (a backend with a GPU lane beside its CPU workers)."""
        has_room = getattr(backend, "has_room", None)
        full = getattr(backend, "full", lambda: False)
        passed: list[list[list[RunSpec]]] = []
        while self.queue and len(self.inflight) < backend.capacity and not full():
            task = self.queue.popleft()
            if has_room is None or has_room(task):
                self._hand_out(backend, task)
            else:
                passed.append(task)
        self.queue.extendleft(reversed(passed))

    def _tasks(self, task_seconds: float) -> list[list[list[RunSpec]]]:
        """The batches, in order, with short batches of one section packed into tasks of
        up to ``task_seconds`` estimated seconds."""
        tasks: list[list[list[RunSpec]]] = []
        seconds = 0.0
        for batch in self.batches:
            cost = sum(map(cost_of, batch))
            if tasks and seconds + cost <= task_seconds and self._alike(tasks[-1][0], batch):
                tasks[-1].append(batch)
                seconds += cost
            else:
                tasks.append([batch])
                seconds = cost
        return tasks

    def _alike(self, one: list[RunSpec], other: list[RunSpec]) -> bool:
        """Batches of one kind (experiment and algorithm) and section: a task reports to
        one section, its progress in one kind's estimated seconds."""
        a, b = one[0], other[0]
        return kind_of(a) == kind_of(b) and self.section(a) == self.section(b)

    def _hand_out(self, backend: Any, task: list[list[RunSpec]]) -> None:
        """Claim ``task``'s runs and give the backend those no one else holds."""
        specs = [spec for batch in task for spec in batch]
        mine, theirs = self.store.claim([s.key for s in specs], self.owner, self.claim_timeout)
        by_key = {s.key: s for s in specs}
        for key in theirs:
            self.waiting[key] = by_key[key]
        for key in set(by_key) - set(mine) - set(theirs):  # stored meanwhile
            self._stored_elsewhere(by_key[key])
        claimed = set(mine)
        kept = [[s for s in batch if s.key in claimed] for batch in task]
        kept = [batch for batch in kept if batch]
        if kept:
            tag = self.next_tag
            self.next_tag += 1
            runs = [spec for batch in kept for spec in batch]
            task = self.tags[tag] = _Tag(self.section(runs[0]), runs)
            self.inflight[tag] = runs
            self.observer.task_progress(task.section, tag, task.kind, 0.0, task.cost)
            backend.submit(tag, kept)

    def _check_waiting(self) -> None:
        """Runs another sweep holds: count those it stored, take over the stale ones."""
        keys = list(self.waiting)
        mine, theirs = self.store.claim(keys, self.owner, self.claim_timeout)
        held = set(theirs)
        for key in keys:
            if key in held:
                continue
            spec = self.waiting.pop(key)
            if key in mine:  # its owner died: ours now
                self.queue.append([[spec]])
            else:
                self._stored_elsewhere(spec)

    def _progress(self, tag: int, amount: float, seconds: float = math.nan) -> None:
        """Work a running task reports, with its estimated seconds (NaN: the task's cost
        spread evenly over its units), each up to the task's own total (a retried task
        reports its work again)."""
        task = self.tags.get(tag)
        if task is None:  # settled already: a late report
            return
        if math.isnan(seconds):
            seconds = amount * task.cost / task.work if task.work > 0 else 0.0
        amount = min(amount, task.work - task.reported)
        seconds = min(seconds, task.cost - task.cost_reported)
        if amount > 0 or seconds > 0:
            task.reported += max(amount, 0.0)
            task.cost_reported += max(seconds, 0.0)
            self.observer.advance(task.section, max(amount, 0.0), max(seconds, 0.0), task.kind)
            self.observer.task_progress(task.section, tag, task.kind, task.cost_reported, task.cost)

    def _settle(self, tag: int) -> None:
        """A finished task's runs are stored: its work and cost not yet reported are
        done too (all of them, run by run, for runs that report none)."""
        task = self.tags.pop(tag)
        if task.reported == 0 and task.cost_reported == 0:
            for spec in task.runs:
                self.observer.advance(task.section, work_of(spec), cost_of(spec), kind_of(spec))
        else:
            rest, cost = task.work - task.reported, task.cost - task.cost_reported
            if rest > 0 or cost > 0:
                self.observer.advance(task.section, max(rest, 0.0), max(cost, 0.0), task.kind)
        self.observer.task_progress(task.section, tag, task.kind, task.cost, task.cost)

    def _commit(self, spec: RunSpec, metrics: dict[str, Any], seconds: float) -> None:
        keep_policy(metrics, spec, self.policies, self.version)  # a file, never in the store
        where = metrics.pop(PROVENANCE, None)  # stored beside the metrics
        if not self.store.put(spec.key, metrics, seconds, self.version, where):
            self.result.duplicates += 1
        self.result.computed += 1
        self.result.run_seconds.append(seconds)
        self.observer.run_finished(self.section(spec), kind_of(spec), cost_of(spec), seconds)

    def _stored_elsewhere(self, spec: RunSpec) -> None:
        self.result.shared += 1
        kind = kind_of(spec)
        self.observer.advance(self.section(spec), work_of(spec), cost_of(spec), kind)
        self.observer.run_finished(self.section(spec), kind, cost_of(spec))


class _Tag:
    """A task handed out: its section, its work and estimated cost, and the work it has
    reported so far."""

    def __init__(self, section: str, runs: list[RunSpec]) -> None:
        self.section, self.runs, self.kind = section, runs, kind_of(runs[0])
        self.work = sum(map(work_of, runs))
        self.cost = sum(map(cost_of, runs))
        self.reported = self.cost_reported = 0.0


def _batches(todo: list[RunSpec], seed_batch: int) -> list[list[RunSpec]]:
    """Group runs of one batchable config into batches of up to ``seed_batch``, the
    batch of largest estimated cost (all its runs together) first, so that no long batch
    starts last and keeps one worker busy while the others idle."""
    groups: dict[tuple[str, str], list[RunSpec]] = {}
    for spec in todo:
        groups.setdefault((spec.experiment, spec.config_json), []).append(spec)
    batches = []
    for specs in groups.values():
        batchable = get_experiment(specs[0].experiment).batchable(settings_of(specs[0]))
        limit = seed_batch if batchable else 1
        batches += [specs[i : i + limit] for i in range(0, len(specs), limit)]
    return sorted(batches, key=lambda batch: -sum(map(cost_of, batch)))
