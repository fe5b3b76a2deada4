"""Figure: VDN's learning curve on the compiled simple_spread beside its curve on mpe2's
Python environment, from two stores (``train --game simple_spread`` and ``train --env
mpe2.simple_spread_v3:parallel_env``), against environment steps; the mean over each
store's runs with the spread of its runs, and each side's final greedy return printed.

Usage: python benchmarks/spread_curves.py COMPILED.sqlite MPE2.sqlite OUT.png
           [--algorithm vdn] [--title TEXT]
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import sys
from pathlib import Path

import numpy as np

STEPS_PER_EPISODE = 25


def curves(path: Path, algorithm: str) -> np.ndarray:
    """(runs, points, 2): [environment steps, greedy return] of ``algorithm``'s runs."""
    if not path.exists():
        raise SystemExit(f"error: no store at {path}")
    with sqlite3.connect(path) as db:
        rows = db.execute(
            "select experiment, metrics from runs where algorithm = ?", (algorithm,)
        ).fetchall()
    if not rows:
        raise SystemExit(f"error: {path} holds no {algorithm} runs")
    found = []
    for experiment, metrics in rows:
        curve = json.loads(metrics)["curve"]
        if experiment == "train":  # [episodes, return, steps]
            found.append([[p[0] * STEPS_PER_EPISODE, p[1]] for p in curve])
        else:  # [budget, success, return, steps], the budget in episodes
            found.append([[p[0] * STEPS_PER_EPISODE, p[2]] for p in curve])
    return np.array(found, dtype=float)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("compiled", type=Path)
    parser.add_argument("mpe2", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--algorithm", default="vdn")
    parser.add_argument("--title", default="VDN on simple_spread: the compiled game and mpe2")
    args = parser.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for label, path in (("compiled game", args.compiled), ("mpe2", args.mpe2)):
        data = curves(path, args.algorithm)
        x, values = data[0, :, 0], data[:, :, 1]
        (line,) = ax.plot(x, values.mean(axis=0), label=f"{label} ({len(data)} runs)")
        if len(data) > 1:
            ax.fill_between(
                x, values.min(axis=0), values.max(axis=0), color=line.get_color(), alpha=0.15
            )
        final = values[:, -1]
        print(f"{label}: {len(data)} runs, final greedy return {final.mean():.2f} "
              f"(runs {', '.join(f'{v:.2f}' for v in final)})")  # fmt: skip
    ax.set_xlabel("environment steps")
    ax.set_ylabel("return of the greedy policy (team)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(args.title, fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120)
    print(f"figure: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
