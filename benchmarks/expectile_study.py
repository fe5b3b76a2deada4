"""Deep CMARL-CD's expectile τ on the climbing games: how upper the record sits.

Two designs have one: the keyed memory with ``record="expectile"`` (a running
τ-expectile of each state's returns; its one-step settings ``REPEATED_DEEP_CMARLCD``
use τ = 0.9), and the first design, ``update="replayed"``, whose record network fits an
expectile. τ → 1 is the paper's max of the returns (for the keyed memory the line
``maximum`` is the table's record itself). Each line: ``--runs`` seeds of deep CMARL-CD
with its one-step settings on one game for compare's budget (5,000 games), the share
ending on an optimal joint action (by expected payoff), and the wall time.

    python benchmarks/expectile_study.py --runs 20                   # the keyed memory
    python benchmarks/expectile_study.py --runs 20 --design replayed # the first design
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

GAMES = ("climbing-ps", "climbing-fs", "climbing")
EXPECTILES = (0.5, 0.8, 0.85, 0.9, 0.95, 0.99, 0.9999)


def keeper(final: dict):
    """Keep each seed's last greedy joint action (of the game's one state)."""
    return lambda k, _, policy: final.__setitem__(k, tuple(policy.table[0]))


def configs(design: str) -> list[tuple[str, object]]:
    """The lines of one design: a label and its settings."""
    from cmarlcd.learners.deep.designs import REPEATED_DEEP_CMARLCD as ONE_STEP

    if design == "replayed":
        return [
            (f"expectile {tau:g}", replace(ONE_STEP, update="replayed", record="maximum",
                                           tolerance=1.0, expectile=tau))
            for tau in EXPECTILES
        ]  # fmt: skip
    lines = [(f"expectile {tau:g}", replace(ONE_STEP, expectile=tau)) for tau in EXPECTILES]
    # the one-step settings before the expectile record: the maximum, ties at 1e-9
    return [*lines, ("maximum", replace(ONE_STEP, record="maximum", tolerance=1e-9))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="seeds per line")
    parser.add_argument("--design", choices=("keyed", "replayed"), default="keyed")
    parser.add_argument("--games", default=",".join(GAMES), help="comma list of compare's games")
    args = parser.parse_args()
    from cmarlcd.experiments import compare as cmp
    from cmarlcd.training.deep import DeepBatch

    for name in args.games.split(","):
        game = cmp.GAMES[name].make(None, np.random.default_rng(0))
        for label, config in configs(args.design):
            seeds = [np.random.SeedSequence(k) for k in range(args.runs)]
            start, final = time.perf_counter(), {}
            batch = DeepBatch(game.spec(), config, seeds, cmp.budget(9))
            batch.train([], keeper(final))
            optimal = sum(bool(game.is_optimal(tuple(map(int, j)))) for j in final.values())
            print(
                f"{name:12s} {args.design} {label:16s} optimal {optimal:3d}/{args.runs} "
                f"({100 * optimal / args.runs:.0f} %)  {time.perf_counter() - start:.1f} s",
                flush=True,
            )


if __name__ == "__main__":
    main()
