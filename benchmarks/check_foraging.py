"""Check: the compiled Level-Based Foraging game against the ``lbforaging`` package, 2.0.0.

For each task, both games step side by side from the same states and actions
(:func:`cmarlcd.testing.foraging.compare_steps`: every reset drawn by the package and
copied into the compiled game; observations, each agent's reward, the team reward and
the termination must be exactly equal at every step), then each resets ``--resets``
times with its own generator and the two reset distributions are compared by
chi-square, statistic by statistic (:func:`~cmarlcd.testing.foraging.compare_resets`).
Exit status 1 if anything differs.

The default tasks cover coop and not, ``-2s``, 2 to 4 players, 1 to 5 foods, grids of 5
to 15 and two penalties.

Usage: python benchmarks/check_foraging.py [--steps 100000] [--resets 100000]
           [--tasks 8x8-2p-2f-coop ...] [--seed 0] [--json]
(the package: pip install -e ".[test]")
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from datetime import date

from cmarlcd.errors import ConfigError
from cmarlcd.games.foraging import Foraging
from cmarlcd.testing.foraging import compare_resets, compare_steps

TASKS = (
    "8x8-2p-2f-coop",
    "2s-8x8-2p-2f-coop",
    "10x10-3p-3f",
    "2s-10x10-3p-3f",
    "15x15-4p-5f",
    "5x5-2p-1f,penalty=0.1",
    "2s-12x12-4p-4f-coop,penalty=0.5",
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--resets", type=int, default=100_000)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    tasks = [Foraging.from_name(task) for task in args.tasks]  # every name checked first
    rows = []
    for rules in tasks:
        start = time.perf_counter()
        steps = compare_steps(rules, args.steps, args.seed)
        stepped = time.perf_counter() - start
        start = time.perf_counter()
        resets = compare_resets(rules, args.resets, args.seed)
        row = {
            "task": rules.name,
            "steps": steps.steps,
            "episodes": steps.episodes,
            "loads": steps.loads,
            "failed_loads": steps.failed_loads,
            "steps_equal": steps.equal,
            "mismatches": steps.mismatches,
            "resets": resets.resets,
            "reset_smallest_p": resets.smallest,
            "reset_statistics": len(resets.p_values),
            "resets_equal": resets.equal,
            "seconds": round(stepped + time.perf_counter() - start, 1),
        }
        rows.append(row)
        if not args.json:
            print(
                f"{row['task']:34} {row['steps']:>8,} steps {row['episodes']:>6,} episodes "
                f"{row['loads']:>6,} loads {row['failed_loads']:>6,} failed: "
                f"{'equal' if row['steps_equal'] else 'DIFFERENT'}; {row['resets']:,} resets, "
                f"smallest p {row['reset_smallest_p']:.3f} of {row['reset_statistics']}: "
                f"{'same distribution' if row['resets_equal'] else 'DIFFERENT'} "
                f"({row['seconds']} s)",
                flush=True,
            )
            for line in row["mismatches"]:
                print(f"    {line}")
    ok = all(r["steps_equal"] and r["resets_equal"] for r in rows)
    if args.json:
        print(json.dumps({"date": str(date.today()), "python": platform.python_version(),
                          "equal": ok, "tasks": rows}, indent=2))  # fmt: skip
    else:
        print(f"{'all equal' if ok else 'NOT EQUAL'} ({date.today()}, alpha 0.001 per task, "
              "Bonferroni over its statistics)")  # fmt: skip
    return 0 if ok else 1


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ConfigError as err:  # a bad task name: one line
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
