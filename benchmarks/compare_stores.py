"""Check that two results stores hold the same runs with the same metrics, bit for bit.

Timings (a run's ``seconds`` and ``*_seconds``, wall times) and the ``device`` a deep run
records (where it ran, not what it computed) are left out. Used to show that a
restructuring changed no number: run the same command with the old and the new code
into two fresh stores, then compare them.

Usage: python benchmarks/compare_stores.py OLD.sqlite NEW.sqlite [--ignore METRIC ...]
           [--drop-setting NAME ...]

``--ignore`` leaves named metrics out as well (e.g. ``memory_megabytes`` when a change
shrinks what a run holds), and the output says which were left out. ``--drop-setting``
leaves a setting out of the runs' configs (a setting added since the old store was
made, whose value keeps the old behaviour), so their runs are matched.
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import sys
from collections.abc import Sequence
from typing import Any


def load(
    path: str, ignore: Sequence[str] = (), drop: Sequence[str] = ()
) -> dict[tuple, dict[str, Any]]:
    """Every run of a store: its key (its config without the settings ``drop``) and its
    metrics without timings and device (nor ``ignore``)."""
    query = "SELECT experiment, algorithm, config, root_seed, run_index, metrics FROM runs"
    with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as conn:
        rows = conn.execute(query).fetchall()
    runs = {}
    for *key, metrics in rows:
        key[2] = without_settings(key[2], drop)
        values = json.loads(metrics)
        timings = [k for k in values if k in ("seconds", "device") or k.endswith("_seconds")]
        for name in set(timings) | {k for k in ignore if k in values}:
            del values[name]
        runs[tuple(key)] = values
    return runs


def without_settings(config: str, drop: Sequence[str]) -> str:
    """A stored config (JSON) without the settings named in ``drop``, at any depth."""
    if not drop:
        return config

    def strip(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if k not in drop}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value

    return json.dumps(strip(json.loads(config)), sort_keys=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old")
    parser.add_argument("new")
    parser.add_argument("--ignore", nargs="*", default=[], metavar="METRIC")
    parser.add_argument("--drop-setting", nargs="*", default=[], metavar="NAME")
    args = parser.parse_args()
    old = load(args.old, args.ignore, args.drop_setting)
    new = load(args.new, args.ignore, args.drop_setting)
    if args.drop_setting:
        print(f"settings left out of the configs: {', '.join(args.drop_setting)}")
    if args.ignore:
        print(f"left out besides timings: {', '.join(args.ignore)}")
    only_old, only_new = set(old) - set(new), set(new) - set(old)
    differ = sorted(k for k in set(old) & set(new) if old[k] != new[k])
    print(f"{len(old)} runs in {args.old}, {len(new)} in {args.new}")
    print(f"only in the first: {len(only_old)}, only in the second: {len(only_new)}")
    print(f"runs with different metrics: {len(differ)}")
    for key in differ[:5]:
        print("  ", key[0], key[1], "seed", key[3], "run", key[4])
    return 1 if only_old or only_new or differ else 0


if __name__ == "__main__":
    sys.exit(main())
