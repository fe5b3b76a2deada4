"""Benchmark: a game's random steps a second, the ``lbforaging`` package's against the
compiled Level-Based Foraging game, on one core, measured in one run.

Both play uniform random actions and reset when an episode ends; each step makes every
agent's observation (the package always does; the compiled game writes them into one
buffer, as a learner reading features has them made). The package is timed over
``--package-steps`` steps, the compiled game (compiled first, outside the clock) over
``--steps``.

Usage: python benchmarks/bench_envs.py [--tasks 8x8-2p-2f-coop ...] [--steps 5000000]
           [--package-steps 50000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from datetime import date

import numpy as np
from numba import njit

from cmarlcd.games.foraging import Foraging
from cmarlcd.games.foraging import kernels as k
from cmarlcd.testing.foraging import package_env

TASKS = ("8x8-2p-2f-coop", "2s-10x10-3p-3f", "15x15-4p-5f")


@njit(cache=True)
def random_steps(env, rng, steps: int, joint, team, features) -> int:
    """``steps`` steps of uniform random actions, resetting at each episode's end; the
    episodes played."""
    episodes = 0
    k.forage_reset(env, rng)
    k.forage_features(env, 0, features)
    for _ in range(steps):
        for i in range(joint.shape[0]):
            joint[i] = int(k.N_ACTIONS * rng.random())
        k.forage_step(env, joint, rng, team)
        k.forage_features(env, 0, features)
        if k.forage_done(env):
            episodes += 1
            k.forage_reset(env, rng)
            k.forage_features(env, 0, features)
    return episodes


def compiled_rate(rules: Foraging, steps: int) -> float:
    env, rng = rules.new_env(), np.random.default_rng(0)
    joint, team = np.zeros(rules.players, np.int64), np.zeros(1)
    features = np.zeros(rules.spec().n_features, np.float32)
    random_steps(env, rng, 100, joint, team, features)  # compiled outside the clock
    start = time.perf_counter()
    random_steps(env, rng, steps, joint, team, features)
    return steps / (time.perf_counter() - start)


def package_rate(rules: Foraging, steps: int) -> float:
    env, rng = package_env(rules), np.random.default_rng(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, done, _, _ = env.step(rng.integers(k.N_ACTIONS, size=rules.players).tolist())
        if done:
            env.reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS))
    parser.add_argument("--steps", type=int, default=5_000_000)
    parser.add_argument("--package-steps", type=int, default=50_000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    for task in args.tasks:
        rules = Foraging.from_name(task)
        theirs = package_rate(rules, args.package_steps)
        ours = compiled_rate(rules, args.steps)
        rows.append(
            {
                "task": rules.name,
                "package_steps_per_second": round(theirs),
                "compiled_steps_per_second": round(ours),
                "ratio": round(ours / theirs, 1),
            }
        )
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    if args.json:
        about = {"date": str(date.today()), "machine": machine}
        print(json.dumps({**about, "python": platform.python_version(), "rows": rows}, indent=2))
        return
    print(f"{machine}, Python {platform.python_version()}, {date.today()}, one core")
    print(f"{'task':26} {'lbforaging':>12} {'compiled':>12} {'ratio':>8}")
    for r in rows:
        print(f"{r['task']:26} {r['package_steps_per_second']:>10,}/s "
              f"{r['compiled_steps_per_second']:>10,}/s {r['ratio']:>7.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
