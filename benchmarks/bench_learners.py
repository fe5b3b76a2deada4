"""Benchmark: games per second of every repeated-game learner, compiled against the same
code run as plain Python, and the wall time of ``cmarl-cd compare``.

* plays/s of each learner (CMARL-CD's Algorithm 1 and the classic learners) on one fixed
  5-agent, 5-action random case-1 game (3,125 joint actions: too many for JAL), through
  the comparison's compiled loop, and the very same loop and rules run as plain Python
  (``NUMBA_DISABLE_JIT=1`` in a subprocess), with their ratio;
* the wall time of the full comparison at ``--runs`` runs per cell (default 50) through
  the real runner into a fresh store (workers, warm-up included).

Usage: python benchmarks/bench_learners.py [--runs 50] [--workers 2] [--skip-compare] [--json]
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

import numpy as np

from cmarlcd.compiled import specialise
from cmarlcd.games.matrix import random_case1
from cmarlcd.registry import REPEATED_LEARNERS
from cmarlcd.training.repeated import play_watching_greedy

#: Games timed per learner: compiled, and as plain Python (much slower).
COMPILED_GAMES = 200_000
INTERPRETED_GAMES = 2_000


def plays_per_second(games: int) -> dict[str, float]:
    """Games/s of every learner on the fixed game (one warm-up call first). CMARL-CD's
    purity threshold is raised out of reach so that it plays every game."""
    from dataclasses import replace

    game = random_case1(5, 5, np.random.default_rng(0))
    spec = game.spec()
    counts = spec.action_counts.copy()
    out = {}
    for name, config in REPEATED_LEARNERS.items():
        if name == "jal":
            continue  # 3,125 joint actions: over JAL's limit (MAX_JOINT_ACTIONS)
        if name == "cmarl-cd":
            config = replace(config, purity_threshold=0.999999999)
        loop = specialise(play_watching_greedy, game=spec.kernels, learner=config.kernels)
        greedy = np.zeros(counts.shape[0], dtype=np.int64)

        def run(n: int, config=config, loop=loop, greedy=greedy) -> int:
            env_rng, rng = np.random.default_rng(1).spawn(2)
            tables = config.new_tables(counts)
            played, _, _ = loop(
                game.new_env(), tables, config.params(), counts, n, env_rng, rng, greedy
            )
            return int(played)

        run(10)
        began = time.perf_counter()
        played = run(games)
        out[name] = played / (time.perf_counter() - began)
    return out


def interpreted() -> dict[str, float]:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    done = subprocess.run(
        [sys.executable, __file__, "--interpreted-only"],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout)


def compare_wall_time(runs: int, workers: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as folder:
        command = [
            sys.executable, "-m", "cmarlcd", "compare", "--runs", str(runs), "--workers",
            str(workers), "--no-progress", "--json", "--store", f"{folder}/s.sqlite",
            "--figures", f"{folder}/f",
        ]  # fmt: skip
        began = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - began
        doc = json.loads(done.stdout)
    return {"runs": doc["runs_computed"], "wall_seconds": wall}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--skip-compare", action="store_true")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--interpreted-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.interpreted_only:
        print(json.dumps(plays_per_second(INTERPRETED_GAMES)))
        return 0
    result: dict = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, "
                    f"Python {platform.python_version()}"}  # fmt: skip
    compiled, plain = plays_per_second(COMPILED_GAMES), interpreted()
    result["plays_per_second"] = {
        name: {"compiled": compiled[name], "python": plain[name],
               "ratio": compiled[name] / plain[name]}
        for name in compiled
    }  # fmt: skip
    if not args.skip_compare:
        result["compare"] = compare_wall_time(args.runs, args.workers)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(result["machine"])
    print("games/s on a 5-agent, 5-action random case-1 game (3,125 joint actions; JAL "
          "plays at most 1,024):")  # fmt: skip
    for name, row in result["plays_per_second"].items():
        print(f"  {name:14s} compiled {row['compiled']:>12,.0f}   plain Python "
              f"{row['python']:>9,.0f}   ratio {row['ratio']:6.0f}x")  # fmt: skip
    if "compare" in result:
        c = result["compare"]
        print(f"cmarl-cd compare --runs {args.runs}: {c['runs']:,} runs in "
              f"{c['wall_seconds']:.1f} s ({args.workers} workers, fresh store)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
