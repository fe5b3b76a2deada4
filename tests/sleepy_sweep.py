"""A sweep of slow toy runs on a given store, for tests that start several sweeps at once.

Usage: python tests/sleepy_sweep.py STORE RUNS SECONDS GO_FILE
Says it is ready (GO_FILE.ready.PID), waits until GO_FILE exists (so sweeps started
together begin together, however long their imports took), runs the sweep in this
process and prints its tally as JSON.
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cmarlcd.experiments import register
from cmarlcd.runs import Experiment, RunSpec, Settings
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore


@dataclass(frozen=True)
class Sleep(Settings):
    seconds: float


def slow_draw(sleep: Sleep, seed: np.random.SeedSequence) -> dict:
    time.sleep(sleep.seconds)
    return {"value": float(np.random.default_rng(seed).random())}


register(Experiment("sleepy", Sleep, slow_draw))


def specs(runs: int, seconds: float) -> list[RunSpec]:
    return [RunSpec.make("sleepy", "alg", Sleep(seconds), 0, i) for i in range(runs)]


def main() -> None:
    store, runs, seconds, go = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
    Path(f"{go}.ready.{os.getpid()}").touch()
    while not Path(go).exists():
        time.sleep(0.01)
    with ResultStore(store) as db:
        done = run_sweep(specs(runs, seconds), db, workers=1)
    print(json.dumps({"computed": done.computed, "reused": done.reused, "shared": done.shared}))


if __name__ == "__main__":
    main()
