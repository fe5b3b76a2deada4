"""Deep CMARL-CD's expectile τ on the climbing games: how upper the record sits (the
first design, ``update="replayed"``, whose record network fits an expectile; the keyed
default's record is the table's maximum).

τ → 1 is the paper's max of the returns; lower τ fits a quantile-like upper envelope.
Each line: ``--runs`` seeds of deep CMARL-CD with its one-step settings
(``REPEATED_DEEP_CMARLCD``) on one game for compare's budget (5,000 games), the share
ending on an optimal joint action (by expected payoff), and the wall time.

    python benchmarks/expectile_study.py --runs 20
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

GAMES = ("climbing-ps", "climbing-fs", "climbing")
EXPECTILES = (0.5, 0.9, 0.99, 0.9999)


def keeper(final: dict):
    """Keep each seed's last greedy joint action (of the game's one state)."""
    return lambda k, _, policy: final.__setitem__(k, tuple(policy.table[0]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="seeds per line")
    args = parser.parse_args()
    from cmarlcd.experiments import compare as cmp
    from cmarlcd.learners.deep_coordination import REPEATED_DEEP_CMARLCD
    from cmarlcd.training.deep import DeepBatch

    for name in GAMES:
        game = cmp.GAMES[name].make(None, np.random.default_rng(0))
        for tau in EXPECTILES:
            config = replace(REPEATED_DEEP_CMARLCD, update="replayed", tolerance=1.0, expectile=tau)
            seeds = [np.random.SeedSequence(k) for k in range(args.runs)]
            start, final = time.perf_counter(), {}
            batch = DeepBatch(game.spec(), config, seeds, cmp.budget(9))
            batch.train([], keeper(final))
            optimal = sum(bool(game.is_optimal(tuple(map(int, j)))) for j in final.values())
            print(
                f"{name:12s} expectile {tau:<7g} optimal {optimal:3d}/{args.runs} "
                f"({100 * optimal / args.runs:.0f} %)  {time.perf_counter() - start:.1f} s",
                flush=True,
            )


if __name__ == "__main__":
    main()
