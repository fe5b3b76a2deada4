"""Two results stores run by run: the same keys, and the same metrics for each (timings
aside). For a change that must not move a number (a restructuring, a faster path with
the same float order): record a fixed-seed store before and after, then

    python benchmarks/compare_stores.py before.sqlite after.sqlite

prints the count of identical runs per experiment and exits 1 on any difference.
"""

from __future__ import annotations

import json
import sqlite3
import sys
from collections import Counter

QUERY = "SELECT experiment, algorithm, config, root_seed, run_index, metrics FROM runs"


def stored(path: str) -> dict[tuple, str]:
    """Every run of a store: key -> its metrics without timings, as canonical JSON."""
    with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as conn:
        rows = conn.execute(QUERY).fetchall()
    runs = {}
    for *key, metrics in rows:
        kept = {
            name: value
            for name, value in json.loads(metrics).items()
            if name != "seconds" and not name.endswith("_seconds")
        }
        runs[tuple(key)] = json.dumps(kept, sort_keys=True)
    return runs


def main(before_path: str, after_path: str) -> int:
    before, after = stored(before_path), stored(after_path)
    same = {key for key in before if after.get(key) == before[key]}
    print(
        f"{len(before)} runs before, {len(after)} after; only before: "
        f"{len(before.keys() - after.keys())}, only after: {len(after.keys() - before.keys())}; "
        f"identical metrics: {len(same)} of {len(before)}"
    )
    totals, identical = Counter(k[0] for k in before), Counter(k[0] for k in same)
    for experiment in sorted(totals):
        print(f"  {experiment}: {identical[experiment]}/{totals[experiment]} identical")
    for key in sorted(before.keys() - same)[:10]:
        print("  differs:", key[0], key[1], "seed", key[3], "run", key[4])
    return 0 if len(same) == len(before) == len(after) else 1


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python benchmarks/compare_stores.py BEFORE.sqlite AFTER.sqlite")
    sys.exit(main(sys.argv[1], sys.argv[2]))
