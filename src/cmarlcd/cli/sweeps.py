"""What every command that computes shares: where its runs are computed and its results
go (:class:`Execution`, whose options are declared once, :func:`with_execution`), the
sweep into the store, and how results are printed."""

from __future__ import annotations

import functools
import importlib.util
import inspect
import json
import typing
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from rich.console import Console

from cmarlcd.cli.options import (
    DEFAULT_FIGURES,
    AddressOption,
    BackendOption,
    DeviceOption,
    FiguresOption,
    GpuTasksOption,
    JsonOption,
    LogDirOption,
    ProgressOption,
    SavePoliciesOption,
    StoreOption,
    WorkersOption,
    check_outputs,
    leave_now,
)
from cmarlcd.cli.progress import RichSweepView
from cmarlcd.devices import DEFAULT_DEVICE, GPU_TASKS, check_device, resolve
from cmarlcd.errors import require
from cmarlcd.experiments import get_experiment
from cmarlcd.limits import check_gpu_tasks, check_workers
from cmarlcd.reports.render import say, show_section
from cmarlcd.reports.section import Section
from cmarlcd.run_logs import check_available
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.backends import check_backend, ray_cluster
from cmarlcd.sweeps.runner import SweepResult, run_sweep
from cmarlcd.sweeps.store import (
    DEFAULT_STORE,
    ResultStore,
    RunRecord,
    check_output_directory,
    discard_if_empty,
)
from cmarlcd.version import __version__

F = TypeVar("F", bound=Callable[..., Any])


@dataclass(frozen=True)
class Execution:
    """Where a command's runs are computed and its results go: the options every command
    that computes takes, declared once (:data:`EXECUTION_OPTIONS`) and checked once
    (:meth:`check`, by :func:`with_execution` before the command runs)."""

    store: Path = DEFAULT_STORE
    figures: Path = DEFAULT_FIGURES
    workers: int | None = None
    progress: bool = True
    backend: str = "process"
    address: str | None = None
    as_json: bool = False
    device: str = DEFAULT_DEVICE
    gpu_tasks: int = GPU_TASKS
    save_policies: Path | None = None
    log_dir: Path | None = None

    def check(self) -> None:
        """Every choice is valid and every output path usable, before anything runs."""
        check_workers(self.workers)
        check_backend(self.backend, self.address)
        check_device_here(self.device, self.backend)
        check_gpu_tasks(self.gpu_tasks)
        check_outputs(self.store, self.figures)
        if self.save_policies is not None:
            check_output_directory(self.save_policies, "save_policies")
        if self.log_dir is not None:
            check_available()
            check_output_directory(self.log_dir, "log_dir")


#: The options of :class:`Execution`, as a command line shows them (in this order).
EXECUTION_OPTIONS: dict[str, tuple[Any, Any]] = {
    "workers": (WorkersOption, None),
    "backend": (BackendOption, "process"),
    "address": (AddressOption, None),
    "as_json": (JsonOption, False),
    "store": (StoreOption, DEFAULT_STORE),
    "figures": (FiguresOption, DEFAULT_FIGURES),
    "progress": (ProgressOption, True),
    "save_policies": (SavePoliciesOption, None),
    "log_dir": (LogDirOption, None),
}
#: The options a command that trains deep learners adds (last).
DEVICE_OPTIONS = {
    "device": (DeviceOption, DEFAULT_DEVICE),
    "gpu_tasks": (GpuTasksOption, GPU_TASKS),
}


def check_device_here(device: str, backend: str) -> None:
    """``device`` is spelt right and, for local workers, torch is installed and sees the
    GPU asked for (a Ray cluster's GPUs are counted when the sweep joins it)."""
    check_device(device)
    if device in (DEFAULT_DEVICE, "auto") or backend == "ray":  # auto: the CPU without torch
        return
    require(has_torch(), "device", f"{device} needs PyTorch: pip install 'cmarl-cd[deep]'")
    resolve(device)


def with_deep_execution(command: F) -> F:
    """:func:`with_execution` for a command that trains deep learners: it also takes
    ``--device`` and ``--gpu-tasks``."""
    return with_execution(command, {**EXECUTION_OPTIONS, **DEVICE_OPTIONS})


def with_execution(command: F, options: dict[str, tuple[Any, Any]] | None = None) -> F:
    """A command that computes: its signature gains the options of :class:`Execution`
    (``options``, default :data:`EXECUTION_OPTIONS`), which are checked before the
    command runs and handed to it as ``run``."""
    declared = EXECUTION_OPTIONS if options is None else options
    hints = typing.get_type_hints(command, include_extras=True)
    own = [
        p.replace(annotation=hints[p.name])
        for p in inspect.signature(command).parameters.values()
        if p.name != "run"
    ]
    shared = [
        inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=kind)
        for name, (kind, default) in declared.items()
    ]

    @functools.wraps(command)
    def wrapper(**options: Any) -> Any:
        run = Execution(**{name: options.pop(name) for name in declared})
        run.check()
        return command(run=run, **options)

    wrapper.__signature__ = inspect.Signature(own + shared)  # type: ignore[attr-defined]
    wrapper.__annotations__ = {p.name: p.annotation for p in own + shared}
    return wrapper  # type: ignore[return-value]


def compute_runs(
    specs: Sequence[RunSpec],
    run: Execution,
    label: str,
    seed_batch: int = 1,
    section: Callable[[RunSpec], str] | None = None,
) -> tuple[list[RunRecord], SweepResult]:
    """Compute what the store lacks of ``specs``; return their records and the tally. A
    store this call created is removed again if the sweep ends with nothing in it."""
    if run.save_policies is not None:
        check_keeps_policies(specs)
    created = not run.store.exists()
    watching, ray_cluster.on_lost = ray_cluster.on_lost, leave_now  # a lost cluster ends
    try:  # the command, even one blocked inside Ray
        with ResultStore(run.store) as store:
            done = run_sweep(
                specs,
                store,
                workers=run.workers,
                version=__version__,
                observer=RichSweepView(show=run.progress),
                description=label,
                seed_batch=seed_batch,
                backend=run.backend,
                address=run.address,
                section=section,
                device=run.device,
                gpu_tasks=run.gpu_tasks,
                policies=run.save_policies,
                logs=run.log_dir,
            )
            return store.get(s.key for s in specs), done
    except BaseException:
        if created:
            discard_if_empty(run.store)
        raise
    finally:
        ray_cluster.on_lost = watching


def check_keeps_policies(specs: Sequence[RunSpec]) -> None:
    """``--save-policies`` where some run keeps a policy (every learner's run does; a
    check of Theorem 1 has none, so ``reproduce`` keeps the others'), else one clear
    error."""

    def keeps(spec: RunSpec) -> bool:
        experiment = get_experiment(spec.experiment)
        return experiment.keeps_policies(experiment.settings_of(spec.config_json))

    if specs and not any(keeps(spec) for spec in specs):
        said = ", ".join(sorted({spec.experiment for spec in specs}))
        require(False, "save_policies", f"the runs of {said} keep no policy (no learner plays)")


def present(section: Section, console: Console | None) -> dict[str, Any]:
    """Show ``section`` on the console (if any); return its JSON document."""
    if console is not None:
        show_section(console, section)
    return section.document()


def run_counts(done: SweepResult, store_path: Path, console: Console | None) -> dict[str, Any]:
    if console is not None:
        shared = f", {done.shared} by another sweep on the same store" if done.shared else ""
        say(
            console,
            f"{done.computed} runs computed, {done.reused} from the store{shared} in "
            f"{done.wall_seconds:.1f} s",
        )
    return {
        "runs_computed": done.computed,
        "runs_reused": done.reused,
        "runs_shared": done.shared,
        "wall_seconds": done.wall_seconds,
        "store": str(store_path),
    }


def where(store: Path, figures: Path, console: Console | None) -> None:
    """The last line of a command: where its results went."""
    if console is not None:
        say(console, f"results: runs in {store}, figures in {figures}/")


def console_for(as_json: bool) -> Console | None:
    """The console tables go to, or None when stdout carries JSON alone."""
    return None if as_json else Console()


def print_results(run: Execution, compute: Callable[[Console | None], dict]) -> None:
    """Compute and print a command's results: tables and a last line saying where they
    went, or its JSON document alone."""
    console = console_for(run.as_json)
    doc = compute(console)
    where(run.store, run.figures, console)
    if run.as_json:
        print(json.dumps(doc, indent=2))


def has_torch() -> bool:
    return importlib.util.find_spec("torch") is not None


def require_torch_for(names: Iterable[str], parameter: str = "algorithms") -> None:
    """Refuse, in one line naming the extra, learners that need PyTorch where it is missing."""
    from cmarlcd import registry

    deep = [name for name in names if registry.needs_torch(name)]
    require(not deep or has_torch(), parameter, needs_torch(deep))


def needs_torch(algorithms: Iterable[str]) -> str:
    names = list(algorithms)
    verb = "needs" if len(names) == 1 else "need"
    return f"{' and '.join(names)} {verb} PyTorch: pip install 'cmarl-cd[deep]'"
