"""Benchmark: what ``--log-dir`` (live curves) costs a run.

Two measurements, in one process:

* **a point**: one curve point of a deep run written (its eval scalars, loss, ε, rate: 7
  tags) to its event file and CSV, repeated ``--points`` times in a fresh folder; the
  mean and the worst microseconds a point;
* **a run**: the same runs (``--algorithms`` on ``--game`` for ``--steps`` environment
  steps, ``--curve-points`` evaluations, 1 worker) computed into a fresh store with and
  without ``--log-dir``, alternately ``--repeats`` times after one warm-up computation (the
  baseline measured in the same run); the runs' own compute seconds from each store, their
  medians and the ratio.

The share of a run that logging costs is then ``points x cost of a point / run seconds``
(printed), which does not depend on the noise of two whole runs; the end-to-end ratio is
printed beside it. Rates of a busy machine differ: say the load (printed) with a figure.

Usage: python benchmarks/bench_run_logs.py [--game G] [--steps N] [--repeats R] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cmarlcd.run_logs import RunLog
from cmarlcd.sweeps.store import ResultStore


def point_cost(points: int) -> dict[str, float]:
    """Microseconds to write one curve point, mean and worst."""
    with tempfile.TemporaryDirectory() as folder:
        log = RunLog(Path(folder))
        times = []
        for k in range(1, points + 1):
            values = {"eval/return": -k * 0.5, "eval/success": 0.0, "eval/episode_steps": 25.0,
                      "train/loss": 1.0 / k, "train/epsilon": 0.05}  # fmt: skip
            start = time.perf_counter()
            log.scalars(1000 * k, values, "steps")
            times.append(time.perf_counter() - start)
        log.close()
    return {"mean_us": 1e6 * statistics.mean(times), "max_us": 1e6 * max(times)}


def run_seconds(args: argparse.Namespace, logs: bool) -> float:
    """The runs' own compute seconds, summed, of one fresh computation."""
    with tempfile.TemporaryDirectory() as folder:
        store = Path(folder) / "s.sqlite"
        command = [sys.executable, "-m", "cmarlcd", "train", "--game", args.game,
                   "--algorithms", args.algorithms, "--steps", str(args.steps), "--runs", "1",
                   "--curve-points", str(args.curve_points), "--workers", "1", "--no-progress",
                   "--store", str(store), "--figures", str(Path(folder) / "f")]  # fmt: skip
        if logs:
            command += ["--log-dir", str(Path(folder) / "logs")]
        subprocess.run(command, check=True, capture_output=True)
        with ResultStore(store, create=False) as db:
            return sum(r.metrics["seconds"] for r in db.records())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--game", default="foraging:8x8-2p-2f-coop")
    parser.add_argument("--algorithms", default="vdn")
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--curve-points", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--points", type=int, default=2000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    cost = point_cost(args.points)
    without, with_logs = [], []
    run_seconds(args, logs=True)  # warm-up: numba's cache and the kernels compiled
    for _ in range(args.repeats):
        without.append(run_seconds(args, logs=False))
        with_logs.append(run_seconds(args, logs=True))
    base, logged = statistics.median(without), statistics.median(with_logs)
    points = args.curve_points + 1  # and the final evaluation's
    doc = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
        "load": os.getloadavg()[0],
        "point_us": cost,
        "run": {
            "game": args.game,
            "algorithms": args.algorithms,
            "steps": args.steps,
            "curve_points": args.curve_points,
        },
        "seconds_without": without,
        "seconds_with": with_logs,
        "share_from_points": points * cost["mean_us"] * 1e-6 / base,
        "ratio_end_to_end": logged / base,
    }
    if args.json:
        print(json.dumps(doc, indent=2))
        return
    print(f"{doc['machine']}, load {doc['load']:.2f}")
    print(f"a point: {cost['mean_us']:.0f} µs mean, {cost['max_us']:.0f} µs worst "
          f"({args.points} points)")  # fmt: skip
    print(
        f"{args.algorithms} on {args.game}, {args.steps:,} steps, {points} points: "
        f"{base:.2f} s without, {logged:.2f} s with --log-dir (medians of {args.repeats})"
    )
    print(
        f"logging's share of a run: {100 * doc['share_from_points']:.3f} % from the "
        f"points' cost; end to end x{doc['ratio_end_to_end']:.3f}"
    )


if __name__ == "__main__":
    main()
