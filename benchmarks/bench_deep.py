"""Benchmark: seed-batched VDN / QMIX on the DSN, B = 1 against B = 50 seeds.

For each mixer, trains B seeds for the same number of learning episodes with the paper's
DSN settings and prints the aggregate environment steps per second (all seeds together,
gradient steps included) for B = 1 and B = 50, and their ratio.

Usage: python benchmarks/bench_deep.py [--episodes E] [--seeds B]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from cmarlcd import runner
from cmarlcd.deep_training import DsnDeepBatch
from cmarlcd.learners.deep_config import DeepConfig


def steps_per_second(mixer: str, seeds: int, episodes: int) -> tuple[float, int]:
    counted = [0.0]
    runner._progress_sink = lambda amount: counted.__setitem__(0, counted[0] + amount)
    batch = DsnDeepBatch(
        DeepConfig(mixer=mixer), [np.random.SeedSequence(k) for k in range(seeds)], episodes
    )
    start = time.perf_counter()
    batch.train([], lambda *args: None)
    elapsed = time.perf_counter() - start
    runner._progress_sink = None
    return counted[0] / elapsed, batch.steps // batch.config.train_every


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=300)
    parser.add_argument("--seeds", type=int, default=50)
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads; {args.episodes} learning episodes per seed"
    )
    for seeds in (1, args.seeds):  # compile the lockstep loop for both batch sizes first
        DsnDeepBatch(DeepConfig(), [np.random.SeedSequence(k) for k in range(seeds)], 2).train(
            [], lambda *a: None
        )
    for mixer in ("vdn", "qmix"):
        single, _ = steps_per_second(mixer, 1, args.episodes)
        batched, updates = steps_per_second(mixer, args.seeds, args.episodes)
        print(
            f"{mixer.upper():5s} B=1: {single:,.0f} env steps/s; B={args.seeds}: "
            f"{batched:,.0f} env steps/s ({updates} batched gradient steps); "
            f"ratio {batched / single:.1f}x"
        )


if __name__ == "__main__":
    main()
