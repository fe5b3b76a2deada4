"""Check: the compiled simple_spread against mpe2 1.1.1's ``simple_spread_v3``.

For each task, both games step side by side from the same states and actions
(:func:`cmarlcd.testing.spread.compare_steps`: every reset drawn by mpe2 and copied into
the compiled game; every observation, each agent's reward, the team reward and the
episode's end within 1e-5 at every step), then each resets ``--resets`` times with its
own generator and the two distributions are compared coordinate by coordinate
(two-sample Kolmogorov-Smirnov, :func:`~cmarlcd.testing.spread.compare_resets`). Exit
status 1 if anything differs.

Usage: python benchmarks/check_spread.py [--steps 100000] [--resets 100000]
           [--tasks "N=3,local_ratio=0.5" ...] [--seed 0] [--json]
(mpe2: pip install -e ".[test]")
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from datetime import date

from cmarlcd.errors import ConfigError
from cmarlcd.games.spread import SimpleSpread
from cmarlcd.testing.spread import TOLERANCE, compare_resets, compare_steps

TASKS = tuple(f"N={n},local_ratio={ratio}" for n in (3, 5) for ratio in (0, 0.5, 1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--resets", type=int, default=100_000)
    parser.add_argument("--tasks", nargs="+", default=list(TASKS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    tasks = [SimpleSpread.from_name(task) for task in args.tasks]  # every name checked first
    rows = []
    for rules in tasks:
        start = time.perf_counter()
        steps = compare_steps(rules, args.steps, args.seed)
        resets = compare_resets(rules, args.resets, args.seed)
        row = {
            "task": rules.name,
            "steps": steps.steps,
            "episodes": steps.episodes,
            "largest_difference": steps.largest_difference,
            "steps_equal": steps.equal,
            "mismatches": steps.mismatches,
            "resets": resets.resets,
            "reset_smallest_p": resets.smallest,
            "reset_coordinates": len(resets.p_values),
            "resets_equal": resets.equal,
            "seconds": round(time.perf_counter() - start, 1),
        }
        rows.append(row)
        if not args.json:
            print(
                f"{row['task']:34} {row['steps']:>8,} steps {row['episodes']:>6,} episodes, "
                f"largest difference {row['largest_difference']:.2g}: "
                f"{'equal' if row['steps_equal'] else 'DIFFERENT'}; {row['resets']:,} resets, "
                f"smallest p {row['reset_smallest_p']:.3f} of {row['reset_coordinates']}: "
                f"{'same distribution' if row['resets_equal'] else 'DIFFERENT'} "
                f"({row['seconds']} s)",
                flush=True,
            )
            for line in row["mismatches"]:
                print(f"    {line}")
    ok = all(r["steps_equal"] and r["resets_equal"] for r in rows)
    if args.json:
        about = {"date": str(date.today()), "python": platform.python_version()}
        print(json.dumps({**about, "tolerance": TOLERANCE, "equal": ok, "tasks": rows}, indent=2))
    else:
        print(f"{'all equal' if ok else 'NOT EQUAL'} ({date.today()}, tolerance {TOLERANCE:g}; "
              "resets: alpha 0.001 per task, Bonferroni over its coordinates)")  # fmt: skip
    return 0 if ok else 1


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ConfigError as err:  # a bad task name: one line
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
