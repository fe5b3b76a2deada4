"""How well each experiment's cost model (its ``cost``: estimated seconds of a run, used to
order the work and to weigh progress) matches the runs' measured compute times in a store.

Prints, for each kind of run (experiment and algorithm), the runs, their measured and
estimated seconds and the ratio. The constants of the cost models were set from such a
table (the quick preset's store on the project's 2-core machine); a ratio far from 1
means a constant to refit. The progress view calibrates each kind on its finished runs
anyway, so the models need only be right within a small factor, and right relative to
one another, for the runs that start before any of their kind has finished.

Usage: python benchmarks/fit_costs.py STORE.sqlite
"""

from __future__ import annotations

import argparse
import sqlite3
from collections import defaultdict

from cmarlcd.experiments import get_experiment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("store")
    args = parser.parse_args()
    query = "SELECT experiment, algorithm, config, wall_seconds FROM runs"
    totals: dict[tuple[str, str], list[float]] = defaultdict(lambda: [0, 0.0, 0.0])
    with sqlite3.connect(f"file:{args.store}?mode=ro", uri=True) as conn:
        for experiment, algorithm, config, seconds in conn.execute(query):
            row = totals[(experiment, algorithm)]
            row[0] += 1
            row[1] += seconds
            kind = get_experiment(experiment)
            row[2] += kind.cost(kind.settings_of(config))
    print(f"{'kind':40s} {'runs':>6s} {'measured s':>11s} {'estimated s':>12s} {'ratio':>6s}")
    for (experiment, algorithm), (runs, measured, estimated) in sorted(totals.items()):
        ratio = measured / estimated if estimated else float("nan")
        kind = f"{experiment}:{algorithm}"
        print(f"{kind:40s} {runs:6d} {measured:11.2f} {estimated:12.2f} {ratio:6.2f}")


if __name__ == "__main__":
    main()
