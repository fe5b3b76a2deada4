"""Benchmark: a game's random steps a second, the package's against the compiled game's,
on one core, measured in one run: Level-Based Foraging (``lbforaging`` 2.0.0) and MPE's
simple_spread (``mpe2`` 1.1.1, discrete actions, its parallel API).

Both play uniform random actions and reset when an episode ends; each step makes every
agent's observation (the packages always do; the compiled game writes them into one
buffer, as a learner reading features has them made). A package is timed over
``--package-steps`` steps, the compiled game (compiled first, outside the clock) over
``--steps``. Tasks: ``foraging:TASK`` or ``simple_spread:OPTIONS``.

Usage: python benchmarks/bench_envs.py [--tasks foraging:8x8-2p-2f-coop ...]
           [--steps 5000000] [--package-steps 50000] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from datetime import date
from typing import Any

import numpy as np

from cmarlcd.compiled import specialise
from cmarlcd.errors import ConfigError
from cmarlcd.games.foraging import Foraging
from cmarlcd.games.spec import GameSpec
from cmarlcd.games.spread import SimpleSpread
from cmarlcd.testing import foraging as foraging_check
from cmarlcd.testing import spread as spread_check

TASKS = (
    "foraging:8x8-2p-2f-coop",
    "foraging:2s-10x10-3p-3f",
    "foraging:15x15-4p-5f",
    "simple_spread:N=3",
    "simple_spread:N=5",
)

game = None  # bound by specialise


def random_steps(env, rng, steps, max_steps, counts, joint, team, features) -> int:
    """Template: ``steps`` steps of uniform random actions, resetting at each episode's
    end (the game's or the cap's); the episodes played."""
    episodes, length = 0, 0
    game.reset(env, rng)
    game.features(env, 0, features)
    for _ in range(steps):
        for i in range(joint.shape[0]):
            joint[i] = int(counts[i] * rng.random())
        game.step(env, joint, rng, team)
        game.features(env, 0, features)
        length += 1
        if game.done(env) or length == max_steps:
            episodes, length = episodes + 1, 0
            game.reset(env, rng)
            game.features(env, 0, features)
    return episodes


def compiled_rate(spec: GameSpec, steps: int) -> float:
    play = specialise(random_steps, game=spec.kernels)
    env, rng = spec.new_env(), np.random.default_rng(0)
    joint, team = np.zeros(spec.n_agents, np.int64), np.zeros(1)
    features = np.zeros(spec.n_features, np.float32)
    args = (spec.max_steps, spec.action_counts, joint, team, features)
    play(env, rng, 100, *args)  # compiled outside the clock
    start = time.perf_counter()
    play(env, rng, steps, *args)
    return steps / (time.perf_counter() - start)


def foraging_rate(rules: Foraging, steps: int) -> float:
    env, rng = foraging_check.package_env(rules), np.random.default_rng(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        _, _, done, _, _ = env.step(rng.integers(6, size=rules.players).tolist())
        if done:
            env.reset()
    return steps / (time.perf_counter() - start)


def spread_rate(rules: SimpleSpread, steps: int) -> float:
    env, rng = spread_check.package_env(rules), np.random.default_rng(0)
    env.reset(seed=0)
    start = time.perf_counter()
    for _ in range(steps):
        actions = {agent: int(rng.integers(5)) for agent in env.agents}
        env.step(actions)
        if not env.agents:
            env.reset()
    return steps / (time.perf_counter() - start)


def parse(task: str) -> tuple[str, Any, Callable[[Any, int], float]]:
    """The task's name, its rules and the function timing its package."""
    kind, _, options = task.partition(":")
    if kind == "foraging":
        rules = Foraging.from_name(options)
        return f"foraging:{rules.name}", rules, foraging_rate
    if kind == "simple_spread":
        spread = SimpleSpread.from_name(options)
        return f"simple_spread:N={spread.N}", spread, spread_rate
    raise ConfigError("tasks", f"{task!r} is not foraging:TASK or simple_spread:OPTIONS")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS))
    parser.add_argument("--steps", type=int, default=5_000_000)
    parser.add_argument("--package-steps", type=int, default=50_000)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    rows = []
    for name, rules, package_rate in [parse(task) for task in args.tasks]:  # all checked first
        theirs = package_rate(rules, args.package_steps)
        ours = compiled_rate(rules.spec(), args.steps)
        rows.append(
            {
                "task": name,
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
    print(f"{'task':34} {'package':>12} {'compiled':>12} {'ratio':>8}")
    for r in rows:
        print(f"{r['task']:34} {r['package_steps_per_second']:>10,}/s "
              f"{r['compiled_steps_per_second']:>10,}/s {r['ratio']:>7.1f}x")  # fmt: skip


if __name__ == "__main__":
    try:
        main()
    except ConfigError as err:  # a bad task: one line
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
