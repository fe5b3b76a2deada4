"""Benchmark: seed-batched VDN / QMIX on the DSN, one seed against batches of seeds.

For each mixer, trains B seeds for the same number of learning episodes with the paper's
DSN settings and prints the aggregate environment steps per second (all seeds together,
gradient steps included) for B = 1 and for batches of B seeds (default 4, 10 and 50),
and the ratios; and, for reference, the generic path (DeepAgent on the PettingZoo
ParallelEnv, one forward pass per step).

Usage: python benchmarks/bench_deep.py [--episodes E] [--seeds B [B ...]]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep.agent import DeepAgent
from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.training.deep import DeepBatch
from cmarlcd.training.episodes import play_episodes


def steps_per_second(mixer: str, seeds: int, episodes: int) -> tuple[float, int]:
    """Aggregate env steps/s of B seeds learning ``episodes`` episodes each, and the
    number of batched gradient steps taken."""
    batch = DeepBatch(
        dsn.SPEC,
        DeepConfig(mixer=mixer),
        [np.random.SeedSequence(k) for k in range(seeds)],
        episodes,
    )
    steps, td_step = [0], batch.model.td_step

    def counted(sample):
        steps[0] += 1
        return td_step(sample)

    batch.model.td_step = counted
    start = time.perf_counter()
    batch.train([], lambda *args: None)
    elapsed = time.perf_counter() - start
    return batch.env_steps / elapsed, steps[0]


def parallel_env_rate(mixer: str, episodes: int) -> float:
    """The generic path: DeepAgent on the PettingZoo ParallelEnv, a forward pass per step."""
    agent = DeepAgent(
        dsn.ACTION_COUNTS, DeepConfig(mixer=mixer), episodes, n_states=dsn.N_STATE_INDICES, seed=0
    )
    start = time.perf_counter()
    stats = play_episodes(dsn.SensorNetworkEnv(), agent, episodes, seed=1)
    return float(stats.lengths.sum()) / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=300)
    parser.add_argument("--seeds", type=int, nargs="+", default=[4, 10, 50])
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads; {args.episodes} learning episodes per seed"
    )
    for seeds in (1, *args.seeds):  # compile the kernels for every batch size first
        sequences = [np.random.SeedSequence(k) for k in range(seeds)]
        warm = DeepBatch(dsn.SPEC, DeepConfig(), sequences, 2)
        warm.train([], lambda *a: None)
        warm.group.sample()
    for mixer in ("vdn", "qmix"):
        single, _ = steps_per_second(mixer, 1, args.episodes)
        for seeds in args.seeds:
            batched, updates = steps_per_second(mixer, seeds, args.episodes)
            print(
                f"{mixer.upper():5s} B={seeds}: {batched:,.0f} env steps/s over all seeds "
                f"({updates} batched gradient steps); vs B=1 ({single:,.0f}/s): "
                f"{batched / single:.1f}x"
            )
        generic = parallel_env_rate(mixer, max(args.episodes // 10, 10))
        print(
            f"{mixer.upper():5s} generic DeepAgent + ParallelEnv loop: {generic:,.0f} env "
            f"steps/s (the compiled B=1 path is {single / generic:.0f}x that)"
        )


if __name__ == "__main__":
    main()
