"""Benchmark: deep CMARL-CD against VDN in the same loop, on the DSN.

Trains B seeds of each learner for the same number of learning episodes (the runner's
stacked model, one-hot state inputs) and prints, per learner, the environment steps per
second over all seeds (gradient steps included), the seconds per gradient step, and deep
CMARL-CD's cost per environment step and per gradient step as a ratio of VDN's measured
in the same run. Deep CMARL-CD runs with its defaults (the keyed update, a gradient step
every 200 env steps: VDN's schedule), with the denser schedule it had before (every 50),
and with its first design (``replayed``, every 50).

Usage: python benchmarks/bench_deep_cmarlcd.py [--episodes E] [--seeds B [B ...]]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import replace

import numpy as np
import torch

from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.learners.deep.designs import REPLAYED_DEEP_CMARLCD
from cmarlcd.training.deep import DeepBatch


def measure(config, seeds: int, episodes: int) -> tuple[float, float]:
    """(env steps/s over all seeds, seconds per batched gradient step)."""
    batch = DeepBatch(dsn.SPEC, config, [np.random.SeedSequence(k) for k in range(seeds)], episodes)
    model, spent, steps = batch.model, [0.0], [0]
    learn = model.learn

    def timed(sample):
        start = time.perf_counter()
        loss = learn(sample)
        spent[0] += time.perf_counter() - start
        steps[0] += 1
        return loss

    model.learn = timed
    start = time.perf_counter()
    batch.train([], lambda *args: None)
    elapsed = time.perf_counter() - start
    return batch.env_steps / elapsed, spent[0] / max(steps[0], 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3_000)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 10])
    args = parser.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads; DSN, {args.episodes} learning episodes per seed"
    )
    deep = DeepCMARLCDConfig()
    learners = {
        "VDN": DeepConfig(),
        "deep CMARL-CD": deep,
        "deep CMARL-CD, a step per 50": replace(deep, train_every=50, target_every=500),
        "deep CMARL-CD, replayed": REPLAYED_DEEP_CMARLCD,
    }
    for config in learners.values():  # compile every kernel first
        measure(config, 1, 5)
    for seeds in args.seeds:
        rates = {name: measure(config, seeds, args.episodes) for name, config in learners.items()}
        vdn_rate, vdn_step = rates["VDN"]
        for name, (rate, step) in rates.items():
            print(
                f"B={seeds:3d} {name:30s} {rate:10,.0f} env steps/s  {step * 1e3:7.2f} ms per "
                f"gradient step   cost per env step {vdn_rate / rate:4.2f}x VDN's, per "
                f"gradient step {step / vdn_step:4.2f}x"
            )


if __name__ == "__main__":
    main()
