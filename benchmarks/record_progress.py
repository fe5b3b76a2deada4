"""Record the progress stream of a real sweep, for the ETA test (tests/test_progress.py).

Runs one sweep of the command line's experiments into a fresh store with a recording
observer, and writes every event the progress view would get, with its time since the
start, one JSON object a line:

    {"t": 0.0, "start": [{"name": ..., "runs": ..., "work": ..., "cost": ..., ...}, ...]}
    {"t": 1.02, "task": ["Tables 3-7", 4, "dsn:cmarl-cd", 0.0, 6.1]}
    {"t": 1.27, "advance": ["Tables 3-7", 2000.0, 0.93, "dsn:cmarl-cd"]}
    {"t": 1.30, "stored": ["Tables 3-7", "dsn:cmarl-cd", 6.1, 5.8]}
    {"t": 61.2, "finish": true}

Usage:
    python benchmarks/record_progress.py compare OUT.jsonl     # compare --runs 3
    python benchmarks/record_progress.py reproduce OUT.jsonl   # reproduce --preset quick
    python benchmarks/record_progress.py dsn OUT.jsonl         # VDN, QMIX, CMARL-CD, LA-OCA

The recordings in tests/data were made on the project's 2-core machine, with 2 workers.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from cmarlcd import __version__
from cmarlcd.cli import reproduce as commands
from cmarlcd.cli.compare import comparison
from cmarlcd.experiments import sensor_network as dsn_exp
from cmarlcd.sweeps.runner import SweepObserver, run_sweep
from cmarlcd.sweeps.store import ResultStore


class Recorder(SweepObserver):
    """Writes each event with its time since the recorder was made."""

    def __init__(self, path: Path) -> None:
        self.file = path.open("w")
        self.zero = time.monotonic()

    def _write(self, **event: Any) -> None:
        self.file.write(json.dumps({"t": round(time.monotonic() - self.zero, 4), **event}) + "\n")

    def start(self, sections) -> None:
        self._write(start=[dataclasses.asdict(s) for s in sections])

    def advance(self, section: str, work: float, cost: float, kind: str = "") -> None:
        self._write(advance=[section, work, cost, kind])

    def task_progress(self, section: str, task: int, kind: str, done: float, total: float) -> None:
        self._write(task=[section, task, kind, done, total])

    def run_finished(self, section: str, kind: str = "", cost: float = 0.0, seconds=math.nan):
        self._write(stored=[section, kind, cost, seconds if math.isfinite(seconds) else None])

    def finish(self) -> None:
        self._write(finish=True)
        self.file.close()


def plan(kind: str) -> tuple[list, Any, int]:
    """The specs, the section of each, and the seed batch of a recorded sweep."""
    if kind == "compare":
        sweep = comparison("cmarl-cd,iql,distributed-q,hysteretic,fmq,lenient,jal,central-q",
                           "climbing,penalty-10,climbing-fs,case1,case2,dsn", 3, 0)  # fmt: skip
        return sweep.specs(), lambda spec: commands.bar_name("compare", spec), 1
    if kind == "dsn":
        from cmarlcd import registry

        learners = tuple(registry.LEARNERS[n] for n in ("cmarl-cd", "la-oca", "vdn", "qmix"))
        sweep = dsn_exp.DsnSweep(
            learners=learners, episodes=(2000, 6000), runs=10, eval_episodes=2000
        )
        return sweep.specs(), lambda spec: "DSN", dsn_exp.SEED_BATCH
    preset = commands.PRESETS["quick"]
    parts = commands.reproduction_plan(preset, 0, {}, True)
    parts[commands.COMPARISON] = commands.comparison_of(preset, 0).specs()
    section = {s.key: commands.bar_name(name, s) for name, specs in parts.items() for s in specs}
    specs = [s for specs in parts.values() for s in specs]
    return specs, lambda spec: section[spec.key], 10


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=("compare", "reproduce", "dsn"))
    parser.add_argument("out", type=Path)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    specs, section, seed_batch = plan(args.kind)
    with tempfile.TemporaryDirectory() as folder, ResultStore(Path(folder) / "s.sqlite") as store:
        done = run_sweep(
            specs,
            store,
            workers=args.workers,
            version=__version__,
            observer=Recorder(args.out),
            seed_batch=seed_batch,
            section=section,
        )
    print(f"{done.computed} runs in {done.wall_seconds:.1f} s -> {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
