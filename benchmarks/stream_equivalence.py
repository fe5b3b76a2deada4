"""Study: does deep CMARL-CD learn what tabular CMARL-CD learns from the same visits?

Tabular CMARL-CD (the paper's DSN settings) plays the paper's DSN and learns; deep
CMARL-CD, with one-hot states (its network can hold any table), is fed exactly the same
visits (:mod:`cmarlcd.testing.streams`). After each checkpoint it prints, over every state
visited so far, the share where both learners' greedy joint actions agree (a candidate
that learns what the table learns: 100 %) and the largest difference of their
coordination degrees (0), with the wall time so far.

Usage: python benchmarks/stream_equivalence.py [--checkpoints 1000,10000,100000]
           [--seed S] [--set NAME=VALUE ...]   (deep CMARL-CD's settings, e.g. lr=1e-2)
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import fields, replace

from cmarlcd.games.sensor_network import SensorNetworkEnv
from cmarlcd.learners import CMARLCDStochastic, DeepCMARLCDConfig
from cmarlcd.learners.degree_agent import DegreeAgent
from cmarlcd.testing.streams import Stream


def config_with(settings: list[str]) -> DeepCMARLCDConfig:
    """Deep CMARL-CD's defaults with ``NAME=VALUE`` settings applied."""
    config = DeepCMARLCDConfig()
    types = {f.name: type(getattr(config, f.name)) for f in fields(config)}
    changes = {}
    for item in settings:
        name, _, value = item.partition("=")
        if name not in types:
            raise SystemExit(f"error: --set: no setting {name!r} (one of {', '.join(types)})")
        kind = types[name]
        changes[name] = value.lower() in ("1", "true") if kind is bool else kind(value)
    return replace(config, **changes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoints", default="1000,10000")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", dest="settings", action="append", default=[])
    args = parser.parse_args()
    marks = sorted({int(part) for part in args.checkpoints.split(",")})
    config = config_with(args.settings)
    env = SensorNetworkEnv()
    counts = [int(env.action_space(agent).n) for agent in env.possible_agents]
    reference = CMARLCDStochastic(counts, seed=args.seed)
    candidate = DegreeAgent(counts, config, marks[-1], n_states=43, seed=args.seed)
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    print(f"# deep CMARL-CD: {', '.join(args.settings) or 'defaults'}; seed {args.seed}")
    print("episodes  states  joint actions agree  agents agree  largest degree difference  wall s")
    stream, start = Stream(env, reference, candidate, args.seed), time.perf_counter()
    for mark in marks:
        stream.play(mark - stream.episodes)
        point = stream.compare()
        print(
            f"{mark:>8,}  {point.states:>6}  {100 * point.agreement:>18.1f} %  "
            f"{100 * point.agent_agreement:>11.1f} %  {point.max_difference:>25.3f}  "
            f"{time.perf_counter() - start:>6.0f}"
        )


if __name__ == "__main__":
    main()
