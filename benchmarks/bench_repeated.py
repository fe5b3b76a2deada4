"""Benchmark: Tables 1-2 at the paper's full protocol, and compiled vs plain Python.

Prints
  * the wall time of the full protocol of Tables 1 and 2 (36 cells x 50 runs) through the
    real runner (fresh store, worker processes, numba warm-up included);
  * games/s of the compiled Algorithm 1 and of the very same code run as plain Python
    (``NUMBA_DISABLE_JIT=1`` in a subprocess) on the same subset of runs, and their ratio.

Usage: python benchmarks/bench_repeated.py [--workers N] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import settings_of
from cmarlcd.sweeps.runner import default_workers, run_sweep
from cmarlcd.sweeps.store import ResultStore
from cmarlcd.training import fit

#: The subset timed in both paths: mid-size case-1 cells (about 1e3-1e4 games a run),
#: small enough for plain Python to finish in seconds.
SUBSET = rep.RepeatedSweep(case=1, agents=(4, 5, 6), actions=(3, 4), runs=3, seed=0)


def time_subset() -> dict[str, float]:
    """Algorithm 1 (:func:`cmarlcd.fit`) on every run of SUBSET: games played, seconds taken."""
    rep._warm_up()
    games, seconds = 0, 0.0
    for spec in SUBSET.specs():
        game, learner = rep.prepare_run(settings_of(spec), spec.seed_sequence())
        start = time.perf_counter()
        games += fit(learner, game).games
        seconds += time.perf_counter() - start
    return {"games": games, "seconds": seconds}


def time_subset_interpreted() -> dict[str, float]:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    out = subprocess.run(
        [sys.executable, __file__, "--subset-only"],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def time_full_protocol(workers: int) -> dict[str, float]:
    specs = rep.paper_sweep(1).specs() + rep.paper_sweep(2).specs()
    with tempfile.TemporaryDirectory() as tmp, ResultStore(Path(tmp) / "bench.sqlite") as store:
        start = time.perf_counter()
        result = run_sweep(specs, store, workers=workers)
        wall = time.perf_counter() - start
        successes = [r.metrics["success"] for r in store.get(s.key for s in specs)]
    return {
        "runs": result.computed,
        "wall_seconds": wall,
        "success_rate": sum(successes) / len(successes),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--subset-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.subset_only:
        print(json.dumps(time_subset()))
        return
    full = time_full_protocol(args.workers)
    compiled = time_subset()
    plain = time_subset_interpreted()
    assert compiled["games"] == plain["games"], "both paths must play the same games"
    compiled_rate = compiled["games"] / compiled["seconds"]
    plain_rate = plain["games"] / plain["seconds"]
    doc = {
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}",
        "workers": args.workers,
        "full_protocol": full,
        "subset_games": compiled["games"],
        "compiled_games_per_s": compiled_rate,
        "plain_python_games_per_s": plain_rate,
        "speedup": compiled_rate / plain_rate,
    }
    if args.json:
        print(json.dumps(doc, indent=2))
        return
    print(f"machine: {doc['machine']}; workers: {args.workers}")
    print(
        f"Tables 1-2 full protocol: {full['runs']} runs in {full['wall_seconds']:.2f} s wall "
        f"(success {100 * full['success_rate']:.1f}%)"
    )
    print(
        f"Algorithm 1 on {compiled['games']:,} games: compiled {compiled_rate:,.0f} games/s, "
        f"plain Python {plain_rate:,.0f} games/s, ratio {doc['speedup']:.0f}x"
    )


if __name__ == "__main__":
    main()
