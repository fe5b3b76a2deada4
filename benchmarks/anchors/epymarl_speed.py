"""The EPyMARL anchor's speed measurement (``epymarl_lbf.py --speed``): steps a second of
both sides measured in the same run, under the same load.

The anchor's long runs overlap whatever else the machine does, and each side's rate is
that of its own hours: they are not comparable. Here, on the anchor's first task, each
algorithm's EPyMARL run (seed 0) and cmarl-cd's command (its seeds stacked, into a fresh
store, so nothing is read back) take turns, ``rounds`` times, each for the anchor's
budget with one greedy test of a few episodes at its start and end on each side. A rate is
a run's budget of environment steps over its wall time, start-up included (EPyMARL's loop
runs until its step count passes the budget; its last test may come earlier) (Python's, torch's and
the compiled kernels' loading on both sides), so a short budget favours neither side's
steady state; cmarl-cd's counts every stacked seed's steps, as the anchor's table does.
Per algorithm the median over rounds of each side and their ratio are reported, with the
load averages before and after each run.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from types import ModuleType
from typing import Any

#: Greedy episodes of each side's tests at the start and the end of a timed run.
TEST_EPISODES = 10


def measure(
    anchor: ModuleType,
    protocol: dict,
    epymarl: Path,
    out: Path,
    rounds: int,
    any_commit: bool,
    clock: Callable[[], float] = time.perf_counter,
) -> dict[str, Any]:
    """Both sides timed in turns on ``protocol``'s first task (``anchor`` is the anchor's
    module: its ``epymarl`` and ``ours`` launch the runs; ``clock`` times them)."""
    task = protocol["tasks"][0]
    quick = {**protocol, "eval_interval": protocol["steps"], "eval_episodes": TEST_EPISODES}
    folder = out / "speed" / time.strftime("%Y%m%d-%H%M%S")  # fresh stores each time
    runs = []
    for round_ in range(rounds):
        for algorithm in protocol["algorithms"]:
            one = {**quick, "algorithms": [algorithm]}
            where = folder / f"{task}-{algorithm}-round{round_}"
            where.mkdir(parents=True, exist_ok=True)
            log = where / "epymarl.log"
            launch = partial(anchor.epymarl, task, algorithm, 0, one, epymarl, log, any_commit)
            theirs = timed(launch, clock)
            del theirs["result"]  # its loop runs until t_env passes t_max: the budget
            mine = timed(partial(anchor.ours, task, one, where, where / "cmarl-cd.log"), clock)
            del mine["result"]
            stacked = protocol["seeds"] * protocol["steps"]
            runs.append({
                "round": round_, "algorithm": algorithm,
                "epymarl": {**theirs, "rate": protocol["steps"] / theirs["seconds"]},
                "cmarl-cd": {**mine, "rate": stacked / mine["seconds"]},
            })  # fmt: skip
            print(f"[{time.strftime('%H:%M:%S')}] {algorithm} round {round_}: EPyMARL "
                  f"{runs[-1]['epymarl']['rate']:,.0f} steps/s, cmarl-cd "
                  f"{runs[-1]['cmarl-cd']['rate']:,.0f}")  # fmt: skip
    medians = {
        algorithm: {
            side: statistics.median(r[side]["rate"] for r in runs if r["algorithm"] == algorithm)
            for side in ("epymarl", "cmarl-cd")
        }
        for algorithm in protocol["algorithms"]
    }
    for rates in medians.values():
        rates["ratio"] = rates["cmarl-cd"] / rates["epymarl"]
    return {"task": task, "protocol": quick, "rounds": rounds, "runs": runs, "medians": medians,
            "machine": anchor.machine()}  # fmt: skip


def timed(run: Callable[[], dict], clock: Callable[[], float]) -> dict[str, Any]:
    """``run()``'s result, its wall time and the load averages around it."""
    before = os.getloadavg()
    start = clock()
    result = run()
    seconds = clock() - start
    return {"result": result, "seconds": seconds,
            "load": {"before": before, "after": os.getloadavg()}}  # fmt: skip


def speed_table(speed: dict) -> str:
    p = speed["protocol"]
    lines = [
        f"Steps a second on LBF {speed['task']}, the two sides in turns ({speed['rounds']} "
        f"round{'s' if speed['rounds'] > 1 else ''}; {p['steps']:,} steps a run, start-up "
        f"included; cmarl-cd: {p['seeds']} seeds stacked, {p['ours']} agents, "
        f"{p.get('layers', 1)} hidden layer(s), step {p.get('step', 'auto')}; EPyMARL: "
        f"{p['agent']} agents, seed 0)",
        "",
        "| algorithm | EPyMARL (median) | cmarl-cd (median) | ratio |",
        "|---|---|---|---|",
    ]
    for algorithm, rates in speed["medians"].items():
        lines.append(f"| {algorithm} | {rates['epymarl']:,.0f} | {rates['cmarl-cd']:,.0f} | "
                     f"{rates['ratio']:.1f}x |")  # fmt: skip
    sides = ("epymarl", "cmarl-cd")
    loads = [r[side]["load"]["before"][0] for r in speed["runs"] for side in sides]
    lines += ["", f"1-minute load average before the runs: {min(loads):.1f} to {max(loads):.1f} "
              f"on {os.cpu_count()} cores."]  # fmt: skip
    return "\n".join(lines)
