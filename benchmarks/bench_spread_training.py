"""Benchmark: VDN learning simple_spread, on the compiled game (``train --game
simple_spread``) against mpe2's Python environment (``train --env
mpe2.simple_spread_v3:parallel_env``), the same settings, measured in one run.

Each side runs one VDN run of ``--episodes`` episodes (25 steps each) with the default
settings (the compiled side one seed in its stacked model, the mpe2 side ``--envs``
copies of the environment), after a short run of each outside the clock (numba's
compilation, the environment's import); a run's own measured seconds, evaluation
included (one greedy evaluation at the end, ``--eval-episodes`` episodes), give its
environment steps a second. Then ``--seeds`` seeds stacked on the compiled game, as a
study runs them.

Usage: python benchmarks/bench_spread_training.py [--episodes 2000] [--envs 16]
           [--seeds 5] [--json]
(mpe2: pip install -e ".[test]"; torch: ".[deep]")
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from datetime import date

import numpy as np

from cmarlcd.experiments import environment as envs
from cmarlcd.experiments import games
from cmarlcd.experiments.episodic import EpisodicRun, run_batch
from cmarlcd.games.spread import SimpleSpread
from cmarlcd.learners.deep.config import DeepConfig

MPE = "mpe2.simple_spread_v3:parallel_env"
STEPS_PER_EPISODE = SimpleSpread().max_cycles


def compiled_seconds(episodes: int, seeds: int, eval_episodes: int) -> float:
    """Wall seconds of ``seeds`` VDN runs stacked on the compiled game."""
    family = games.SIMPLE_SPREAD
    settings = EpisodicRun(
        DeepConfig(), (episodes,), eval_episodes, 0, eval_episodes,
        family.options(SimpleSpread()),
    )  # fmt: skip
    sequences = [np.random.SeedSequence(k) for k in range(seeds)]
    start = time.perf_counter()
    run_batch(family.game, settings, sequences)
    return time.perf_counter() - start


def mpe2_seconds(episodes: int, copies: int, eval_episodes: int) -> float:
    """Wall seconds of one VDN run on mpe2 (``train --env``'s own run function)."""
    settings = envs.EnvRun(
        MPE, (("continuous_actions", False),), DeepConfig(), episodes, eval_episodes, 1,
        "sum", "state", copies,
    )  # fmt: skip
    start = time.perf_counter()
    envs.run(settings, np.random.SeedSequence(0))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=2000)
    parser.add_argument("--envs", type=int, default=envs.DEFAULT_ENVS)
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)
    compiled_seconds(20, 1, 2)  # compiled outside the clock
    mpe2_seconds(20, args.envs, 2)
    steps = args.episodes * STEPS_PER_EPISODE
    ours = compiled_seconds(args.episodes, 1, args.eval_episodes)
    theirs = mpe2_seconds(args.episodes, args.envs, args.eval_episodes)
    stacked = compiled_seconds(args.episodes, args.seeds, args.eval_episodes)
    row = {
        "steps_per_run": steps,
        "compiled_steps_per_second": round(steps / ours),
        "mpe2_steps_per_second": round(steps / theirs),
        "ratio": round(theirs / ours, 1),
        "stacked_seeds": args.seeds,
        "stacked_steps_per_second": round(args.seeds * steps / stacked),
        "projected_2m_minutes_stacked": round(
            2_000_000 * args.seeds / (args.seeds * steps / stacked) / 60, 1
        ),
    }
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    if args.json:
        print(json.dumps({"date": str(date.today()), "machine": machine, **row}, indent=2))
        return
    print(f"{machine}, Python {platform.python_version()}, {date.today()}, one thread")
    ours, theirs = row["compiled_steps_per_second"], row["mpe2_steps_per_second"]
    print(f"VDN, {steps:,} steps a run: compiled {ours:,}/s, mpe2 ({args.envs} copies) "
          f"{theirs:,}/s: {row['ratio']}x")  # fmt: skip
    print(f"{args.seeds} seeds stacked on the compiled game: "
          f"{row['stacked_steps_per_second']:,} steps/s in all; 2M steps each in "
          f"{row['projected_2m_minutes_stacked']} min")  # fmt: skip


if __name__ == "__main__":
    main()
