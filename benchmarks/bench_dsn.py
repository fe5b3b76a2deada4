"""Benchmark: the DSN (Section V-A) with the tabular learners.

Prints
  * env steps/s of CMARL-CD learning on the DSN through the compiled loop and through the
    generic PettingZoo ParallelEnv loop, on the same episodes (same seeds, so the very
    same steps), and their ratio;
  * the wall time of the full protocol of Tables 3-7 for CMARL-CD and LA-OCA (50 runs
    each to 500k episodes, 50k-episode evaluations at 100k, 300k and 500k) through the
    real runner with a fresh store (skip with --no-full).

Usage: python benchmarks/bench_dsn.py [--workers N] [--episodes E] [--no-full]
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from cmarlcd.experiments import sensor_network as sn
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic, StochasticConfig
from cmarlcd.sweeps.runner import default_workers, run_sweep
from cmarlcd.sweeps.store import ResultStore
from cmarlcd.training import TabularRun, play_episodes


def compiled_rate(episodes: int) -> tuple[int, float]:
    TabularRun(dsn.SPEC, StochasticConfig(), *rngs()).train(5)  # compile (or load the cache)
    run = TabularRun(dsn.SPEC, StochasticConfig(), *rngs())
    start = time.perf_counter()
    steps = run.train(episodes)
    return steps, time.perf_counter() - start


def python_rate(episodes: int) -> tuple[int, float]:
    learner = CMARLCDStochastic(dsn.ACTION_COUNTS, n_states=dsn.N_STATE_INDICES, seed=2)
    start = time.perf_counter()
    stats = play_episodes(dsn.SensorNetworkEnv(), learner, episodes, seed=1)
    return int(stats.lengths.sum()), time.perf_counter() - start


def rngs() -> tuple[np.random.Generator, np.random.Generator]:
    return np.random.default_rng(1), np.random.default_rng(2)


def full_protocol(workers: int) -> float:
    sweep = sn.DsnSweep()
    with tempfile.TemporaryDirectory() as tmp, ResultStore(Path(tmp) / "b.sqlite") as store:
        start = time.perf_counter()
        run_sweep(sweep.specs(), store, workers=workers)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument("--episodes", type=int, default=5000, help="episodes in each path")
    parser.add_argument("--no-full", action="store_true", help="skip the full protocol")
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; workers: {args.workers}"
    )
    fast_steps, fast_seconds = compiled_rate(args.episodes)
    slow_steps, slow_seconds = python_rate(args.episodes)
    assert fast_steps == slow_steps, "both paths must take the same steps"
    fast, slow = fast_steps / fast_seconds, slow_steps / slow_seconds
    print(
        f"CMARL-CD learning on the DSN, {args.episodes:,} episodes = {fast_steps:,} steps: "
        f"compiled {fast:,.0f} steps/s, ParallelEnv loop {slow:,.0f} steps/s, "
        f"ratio {fast / slow:,.0f}x"
    )
    if not args.no_full:
        wall = full_protocol(args.workers)
        print(f"Tables 3-7 full protocol, CMARL-CD + LA-OCA (100 runs): {wall:.1f} s wall")


if __name__ == "__main__":
    main()
