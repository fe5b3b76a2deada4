"""Benchmark: the deep learners on a GPU against the CPU, measured in the same run.

Prints, for each device (the CPU first, as the baseline, then ``--device``):

  * a deep pairing of the blood battlefield (VDN against QMIX, the paper's battlefield
    settings) learning ``--episodes`` episodes per match with 1, 10 and 30 rounds stacked
    in one model (the tournament's ``--seed-batch``): learning turns/s over all rounds,
    and the ratio to the CPU;
  * the DSN's deep rows (VDN, QMIX, deep CMARL-CD, ``--dsn-seeds`` seeds stacked):
    environment steps/s over all seeds, and the ratio to the CPU;
  * what one gradient step of the stacked pairing costs in its three parts: the batch
    drawn on the host and sent over, the step, the weights copied back for the compiled
    loop (the copies are what the device adds);

then projects the paper's full tournament (30 rounds x 6 pairings x (500k + 500k)
episodes per match; 5 pairings have a deep side) on one such device: the deep pairings'
learning one after another on the device, 30 rounds stacked, from the rate measured here;
the tabular pairing and every match's evaluation on ``--cores`` CPU cores, from the
CPU rates measured here (one core each).

Usage: python benchmarks/bench_gpu.py [--device auto] [--episodes 2000]
       [--rounds 1 10 30] [--dsn-episodes 300] [--dsn-seeds 50] [--cores 16] [--cpu-rounds 10]

Runs anywhere; with no GPU it measures the CPU alone and says so.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from cmarlcd import devices
from cmarlcd.experiments import tournament as tour
from cmarlcd.games import battlefield
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep_config import DeepConfig
from cmarlcd.learners.deep_coordination import DeepCMARLCDConfig
from cmarlcd.training.deep import DeepBatch
from cmarlcd.training.match import Match, MatchBatch

LEARNERS = tour.battlefield_learners()
PAPER_ROUNDS, PAPER_EPISODES, DEEP_PAIRINGS = 30, 500_000, 5


def stacked_match_turns(rounds: int, episodes: int) -> tuple[float, float]:
    """(learning turns/s over all rounds, turns per match-episode) of ``rounds`` VDN vs
    QMIX matches learning together on the current device."""
    positions = [(0, 1) if r % 2 == 0 else (1, 0) for r in range(rounds)]
    pair = (LEARNERS["vdn"], LEARNERS["qmix"])

    def batch(length: int) -> MatchBatch:
        streams = [np.random.default_rng(r).spawn(3) for r in range(rounds)]
        envs = [env for env, _, _ in streams]
        sides = [(s0, s1) for _, s0, s1 in streams]
        return MatchBatch(battlefield.SPEC, pair, positions, envs, sides, length)

    batch(2).learn()  # compile, and start the device
    played = batch(episodes)
    _synchronise()
    start = time.perf_counter()
    played.learn()
    _synchronise()
    turns = sum(m.turns for m in played.matches)
    return turns / (time.perf_counter() - start), turns / (rounds * episodes)


def step_costs(rounds: int, episodes: int, repeats: int = 30) -> dict[str, float]:
    """Milliseconds of the three parts of one gradient step of the VDN side of ``rounds``
    stacked VDN vs QMIX matches, after ``episodes`` learning episodes filled its ring: the
    batch drawn on the host and sent to the device, the step itself, and the weights
    copied back for the compiled loop."""
    positions = [(0, 1) if r % 2 == 0 else (1, 0) for r in range(rounds)]
    streams = [np.random.default_rng(r).spawn(3) for r in range(rounds)]
    played = MatchBatch(
        battlefield.SPEC,
        (LEARNERS["vdn"], LEARNERS["qmix"]),
        positions,
        [env for env, _, _ in streams],
        [(s0, s1) for _, s0, s1 in streams],
        episodes,
    )
    played.learn()
    group = played.groups[0]
    batch = group.sample()

    def timed(part) -> float:
        part()
        _synchronise()
        start = time.perf_counter()
        for _ in range(repeats):
            part()
        _synchronise()
        return 1000 * (time.perf_counter() - start) / repeats

    return {
        "batch to the device": timed(group.sample),
        "gradient step": timed(lambda: group.model.learn(batch)),
        "weights back": timed(group._copy_weights),
    }


def evaluation_turns(a: str, b: str, episodes: int) -> float:
    """Greedy evaluation turns/s of one match after a short learning stage (compiled,
    on the CPU whatever the device: acting reads a copy of the weights)."""
    env, sides = np.random.default_rng(0), (np.random.default_rng(1), np.random.default_rng(2))
    played = Match(battlefield.SPEC, (LEARNERS[a], LEARNERS[b]), env, sides, 200)
    played.learn()
    played.evaluate(2, np.random.default_rng(3))
    start = time.perf_counter()
    result = played.evaluate(episodes, np.random.default_rng(3))
    return result.turns / (time.perf_counter() - start)


def tabular_learning_turns(episodes: int) -> float:
    """Learning turns/s of a CMARL-CD vs LA-OCA match (the one tabular pairing)."""
    env, sides = np.random.default_rng(0), (np.random.default_rng(1), np.random.default_rng(2))
    pair = (LEARNERS["cmarl-cd"], LEARNERS["la-oca"])
    Match(battlefield.SPEC, pair, env, sides, 2).learn()
    played = Match(battlefield.SPEC, pair, env, sides, episodes)
    start = time.perf_counter()
    played.learn()
    return played.turns / (time.perf_counter() - start)


def dsn_steps(config, seeds: int, episodes: int) -> float:
    """Environment steps/s of ``seeds`` DSN seeds learning together on the current device."""
    sequences = [np.random.SeedSequence(k) for k in range(seeds)]
    DeepBatch(dsn.SPEC, config, sequences, 2).train([], lambda *a: None)  # compile
    batch = DeepBatch(dsn.SPEC, config, sequences, episodes)
    _synchronise()
    start = time.perf_counter()
    batch.train([], lambda *a: None)
    _synchronise()
    return batch.env_steps / (time.perf_counter() - start)


def _synchronise() -> None:
    if devices.current().startswith("cuda"):
        torch.cuda.synchronize()


def measure(device: str, args: argparse.Namespace, rounds: list[int]) -> dict:
    """Every rate of this benchmark on ``device``."""
    rates: dict = {"match": {}, "dsn": {}}
    with devices.running_on(device):
        for r in rounds:
            rates["match"][r], rates["turns_per_episode"] = stacked_match_turns(r, args.episodes)
            print(f"  battlefield VDN vs QMIX, {r:2d} rounds stacked: "
                  f"{rates['match'][r]:>9,.0f} learning turns/s")  # fmt: skip
        for name, config in (
            ("VDN", DeepConfig(mixer="vdn")),
            ("QMIX", DeepConfig(mixer="qmix")),
            ("deep CMARL-CD", DeepCMARLCDConfig()),
        ):
            rates["dsn"][name] = dsn_steps(config, args.dsn_seeds, args.dsn_episodes)
            print(f"  DSN {name}, {args.dsn_seeds} seeds stacked: "
                  f"{rates['dsn'][name]:>9,.0f} env steps/s")  # fmt: skip
        costs = step_costs(max(rounds), max(args.episodes // 4, 200))
        parts = ", ".join(f"{part} {ms:.2f} ms" for part, ms in costs.items())
        print(f"  one gradient step of {max(rounds)} stacked rounds: {parts}")
    return rates


def project(gpu: dict, cpu_eval: float, cpu_tabular: float, cores: int) -> None:
    """The paper's full tournament on one device and ``cores`` CPU cores."""
    turns = gpu["turns_per_episode"] * PAPER_EPISODES  # turns of one match's learning
    stacked = max(gpu["match"])  # the most rounds stacked that were measured
    per_pairing = PAPER_ROUNDS * turns / gpu["match"][stacked]
    deep_learning = DEEP_PAIRINGS * per_pairing
    matches = PAPER_ROUNDS * (DEEP_PAIRINGS + 1)
    cpu_work = matches * turns / cpu_eval + PAPER_ROUNDS * turns / cpu_tabular
    print(
        f"  projection ({stacked} rounds stacked per model): deep learning "
        f"{deep_learning / 60:.1f} min on the device ({per_pairing / 60:.1f} min a pairing); "
        f"evaluation and the tabular pairing {cpu_work / cores / 60:.1f} min on {cores} cores; "
        f"the tournament about {(deep_learning + cpu_work / cores) / 60:.0f} min if the two "
        f"overlap poorly (the sum), {max(deep_learning, cpu_work / cores) / 60:.0f} min if well"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="auto")
    parser.add_argument("--episodes", type=int, default=2_000, help="learning episodes a match")
    parser.add_argument("--rounds", type=int, nargs="+", default=[1, 10, 30])
    parser.add_argument("--cpu-rounds", type=int, default=10, help="most rounds on the CPU")
    parser.add_argument("--dsn-episodes", type=int, default=300)
    parser.add_argument("--dsn-seeds", type=int, default=50)
    parser.add_argument("--cores", type=int, default=16, help="CPU cores of the projection")
    args = parser.parse_args()
    device = devices.resolve(args.device)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads; device {devices.describe(device)}; "
        f"{args.episodes} learning episodes a match"
    )
    print("cpu (the baseline):")
    cpu_rounds = [r for r in args.rounds if r <= args.cpu_rounds] or [min(args.rounds)]
    cpu = measure("cpu", args, cpu_rounds)
    cpu_eval = evaluation_turns("vdn", "qmix", 2_000)
    cpu_tabular = tabular_learning_turns(args.episodes)
    print(f"  evaluation {cpu_eval:,.0f} turns/s, tabular learning {cpu_tabular:,.0f} turns/s")
    if device == "cpu":
        print("no GPU here: the CPU alone was measured")
        project(cpu, cpu_eval, cpu_tabular, args.cores)
        return
    print(f"{devices.describe(device)}:")
    gpu = measure(device, args, args.rounds)
    for r in cpu_rounds:
        print(f"  {r:2d} rounds: {gpu['match'][r] / cpu['match'][r]:.1f}x the CPU")
    for name, rate in gpu["dsn"].items():
        print(f"  DSN {name}: {rate / cpu['dsn'][name]:.1f}x the CPU")
    project(gpu, cpu_eval, cpu_tabular, args.cores)


if __name__ == "__main__":
    main()
