"""Benchmark: the deep learners on a GPU against the CPU, measured in the same run.

Prints, for each device (the CPU first, as the baseline, then ``--device``):

  * a deep pairing of the blood battlefield (VDN against QMIX, the paper's battlefield
    settings) learning ``--episodes`` episodes per match with 1, 10 and 30 rounds stacked
    in one model (the tournament's ``--seed-batch``): learning turns/s over all rounds,
    and the ratio to the CPU;
  * the DSN's deep rows (VDN, QMIX, deep CMARL-CD, ``--dsn-seeds`` seeds stacked):
    environment steps/s over all seeds, and the ratio to the CPU;
  * of those stacked pairings' learning, the share of time in the gradient work (the
    rest is acting, in the compiled loops on the CPU whatever the device): the acting
    rate is what no card can raise;
  * what one gradient step of the stacked pairing costs in its three parts: the batch
    drawn on the host and sent over, the step, the weights copied back for the compiled
    loop (the copies are what the device adds);
  * ``--tasks`` processes sharing the device at once, each learning its own stacked
    pairing of ``--task-rounds`` rounds (a sweep's deep tasks with ``--gpu-tasks``):
    learning turns/s over all of them;

then projects the paper's full tournament (30 rounds of its 10 pairings, each an
algorithm against another or itself, 7 of them with a deep side; 500k learning and 500k
evaluation episodes a match) on one such device and ``--cores`` cores, as a sweep runs
it: each deep task (``--task-rounds`` rounds stacked) learns and then evaluates in one of
``--gpu-tasks`` worker processes sharing the device, at the rate measured for that many;
the tabular matches on the other cores.

Usage: python benchmarks/bench_gpu.py [--device auto] [--episodes 2000]
       [--rounds 1 10 30] [--dsn-episodes 300] [--dsn-seeds 50] [--cores 16]
       [--cpu-rounds 10] [--tasks 1 4 8 15] [--task-rounds 10]

Runs anywhere; with no GPU it measures the CPU alone and says so.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import multiprocessing
import os
import platform
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import torch

from cmarlcd import devices
from cmarlcd.experiments import tournament as tour
from cmarlcd.games import battlefield
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig
from cmarlcd.training import deep_side
from cmarlcd.training.deep import DeepBatch
from cmarlcd.training.match import Match, MatchBatch

LEARNERS = tour.battlefield_learners()
PAPER_NAMES = ("cmarl-cd", "la-oca", "vdn", "qmix")
PAPER_PAIRINGS = tour.pairings(PAPER_NAMES)
DEEP_PAIRINGS = sum(1 for pair in PAPER_PAIRINGS if {"vdn", "qmix"} & set(pair))
PAPER_ROUNDS, PAPER_EPISODES = tour.PAPER_ROUNDS, tour.PAPER_LEARN_EPISODES


def deep_pairing(rounds: int, length: int) -> MatchBatch:
    """``rounds`` VDN vs QMIX matches of ``length`` learning episodes, stacked."""
    positions = [(0, 1) if r % 2 == 0 else (1, 0) for r in range(rounds)]
    streams = [np.random.default_rng(r).spawn(3) for r in range(rounds)]
    envs = [env for env, _, _ in streams]
    sides = [(s0, s1) for _, s0, s1 in streams]
    pair = (LEARNERS["vdn"], LEARNERS["qmix"])
    return MatchBatch(battlefield.SPEC, pair, positions, envs, sides, length)


@contextlib.contextmanager
def gradient_clock() -> Iterator[list[float]]:
    """Seconds spent in the deep groups' gradient work while the block runs:
    ``clock[0]``. That is all of :meth:`DeepGroup.train`: the step and target copy, the
    weights copied back, but also the replay batch drawn on the host and the masks sent,
    which no card removes, so the acting rate derived from it is a little high."""
    clock = [0.0]
    train = deep_side.DeepGroup.train

    def timed(group: deep_side.DeepGroup) -> None:
        start = time.perf_counter()
        train(group)
        _synchronise()
        clock[0] += time.perf_counter() - start

    deep_side.DeepGroup.train = timed
    try:
        yield clock
    finally:
        deep_side.DeepGroup.train = train


def stacked_match_turns(rounds: int, episodes: int) -> tuple[float, float, float]:
    """(learning turns/s over all rounds, turns per match-episode, acting turns/s: the
    same with the gradient work's time taken out) of ``rounds`` VDN vs QMIX matches
    learning together on the current device."""
    deep_pairing(rounds, 2).learn()  # compile, and start the device
    played = deep_pairing(rounds, episodes)
    _synchronise()
    with gradient_clock() as clock:
        start = time.perf_counter()
        played.learn()
        _synchronise()
        seconds = time.perf_counter() - start
    turns = sum(m.turns for m in played.matches)
    return turns / seconds, turns / (rounds * episodes), turns / (seconds - clock[0])


#: Seconds a process sharing the device may take to compile and build its pairing, and
#: then to learn it, before the benchmark gives up on it (rather than wait forever).
READY_SECONDS, LEARN_SECONDS = 600.0, 1800.0


def _task(device: str, rounds: int, episodes: int, threads: int, ready: Any) -> tuple:
    """One of several processes sharing the device: (turns, start, end) of its stacked
    pairing's learning, started with the others. A failure before the start breaks the
    barrier, so that the others and the parent do not wait for it."""
    try:
        torch.set_num_threads(threads)  # as a sweep's worker: its share of the cores
        devices.set_current(device)
        deep_pairing(rounds, 2).learn()
        played = deep_pairing(rounds, episodes)
    except BaseException:
        ready.abort()
        raise
    ready.wait(READY_SECONDS)
    start = time.time()
    played.learn()
    _synchronise()
    return sum(m.turns for m in played.matches), start, time.time()


def shared_device_turns(device: str, tasks: int, rounds: int, episodes: int, cores: int) -> float:
    """Learning turns/s over ``tasks`` processes, each a stacked pairing of ``rounds``
    rounds, sharing ``device`` at once, with the threads a sweep of ``cores`` workers
    gives each (spawned: a process that has started CUDA cannot fork)."""
    context = multiprocessing.get_context("spawn")
    threads = max(1, (os.cpu_count() or 1) // cores)
    with context.Manager() as manager:
        ready = manager.Barrier(tasks + 1)
        with context.Pool(tasks) as pool:
            pending = [
                pool.apply_async(_task, (device, rounds, episodes, threads, ready))
                for _ in range(tasks)
            ]
            try:
                ready.wait(READY_SECONDS)  # every process has compiled and built its pairing
            except threading.BrokenBarrierError:
                for task in pending:  # the failure of the process that broke it
                    if task.ready():
                        task.get()
                raise
            done = [task.get(LEARN_SECONDS) for task in pending]
    turns = sum(t for t, _, _ in done)
    return turns / (max(end for _, _, end in done) - min(start for _, start, _ in done))


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


def measure(device: str, args: argparse.Namespace, rounds: list[int], tasks: list[int]) -> dict:
    """Every rate of this benchmark on ``device``."""
    rates: dict = {"match": {}, "acting": {}, "dsn": {}, "shared": {}}
    with devices.running_on(device):
        for r in rounds:
            rate, rates["turns_per_episode"], acting = stacked_match_turns(r, args.episodes)
            rates["match"][r], rates["acting"][r] = rate, acting
            print(f"  battlefield VDN vs QMIX, {r:2d} rounds stacked: {rate:>9,.0f} learning "
                  f"turns/s; gradient work {1 - rate / acting:.0%} of it, acting alone "
                  f"{acting:,.0f} turns/s")  # fmt: skip
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
    for count in tasks:
        rates["shared"][count] = shared_device_turns(
            device, count, args.task_rounds, args.episodes, args.cores
        )
        print(f"  {count:2d} processes at once, {args.task_rounds} rounds stacked each: "
              f"{rates['shared'][count]:>9,.0f} learning turns/s in all")  # fmt: skip
    return rates


def project(rates: dict, cpu_eval: float, cpu_tabular: float, args: argparse.Namespace) -> None:
    """The paper's full tournament on this device and ``args.cores`` cores, for each
    number of deep tasks sharing the device that was measured: the deep tasks go in waves
    of that many, each task learning at its share of the rate measured for that many at
    once and then evaluating on its core; the tabular matches on the other cores. The
    floor is the same with the gradient work free (acting at the rate measured alone)."""
    turns = rates["turns_per_episode"] * PAPER_EPISODES  # a match's learning, and about
    deep = DEEP_PAIRINGS * PAPER_ROUNDS  # its evaluation (500k episodes each)
    tabular = (len(PAPER_PAIRINGS) - DEEP_PAIRINGS) * PAPER_ROUNDS
    tasks = math.ceil(deep / args.task_rounds)
    # the acting rate of a task's stack, or of the nearest stack measured
    acting = rates["acting"][min(rates["acting"], key=lambda r: abs(r - args.task_rounds))]
    print(
        f"  projection of the paper's tournament: {deep} deep matches in {tasks} tasks of "
        f"{args.task_rounds} rounds, {tabular} tabular matches, {turns:,.0f} turns a "
        f"match's learning and as many its evaluation:"
    )
    for count, rate in rates["shared"].items():
        waves = math.ceil(tasks / count)
        evaluating = args.task_rounds * turns / cpu_eval
        task = args.task_rounds * turns / (rate / count) + evaluating
        floor = args.task_rounds * turns / acting + evaluating
        cores = max(1, args.cores - count)
        tabular_seconds = tabular * (turns / cpu_tabular + turns / cpu_eval) / cores
        print(
            f"    --gpu-tasks {count:2d}: deep tasks in {waves} waves of {task / 60:.1f} min "
            f"(floor {floor / 60:.1f}), tabular {tabular_seconds / 60:.1f} min on {cores} "
            f"cores: the tournament about {max(waves * task, tabular_seconds) / 60:.0f} min "
            f"(floor {max(waves * floor, tabular_seconds) / 60:.0f})"
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
    parser.add_argument(
        "--tasks", type=int, nargs="+", default=[1, 4, 8, 15], help="processes sharing it"
    )
    parser.add_argument("--task-rounds", type=int, default=tour.SEED_BATCH)
    args = parser.parse_args()
    device = devices.resolve(args.device)
    here = os.cpu_count() or 1
    print(
        f"machine: {platform.machine()}, {here} cores, torch {torch.__version__}, "
        f"{torch.get_num_threads()} threads; device {devices.describe(device)}; "
        f"{args.episodes} learning episodes a match"
    )
    print("cpu (the baseline):")
    cpu_rounds = [r for r in args.rounds if r <= args.cpu_rounds] or [min(args.rounds)]
    # processes sharing the CPU (a process per core at most) only where it stands for the
    # device: the projection uses those of the device
    cpu_tasks = ([t for t in args.tasks if t <= here] or [1]) if device == "cpu" else []
    cpu = measure("cpu", args, cpu_rounds, cpu_tasks)
    cpu_eval = evaluation_turns("vdn", "qmix", 2_000)
    cpu_tabular = tabular_learning_turns(args.episodes)
    print(f"  evaluation {cpu_eval:,.0f} turns/s, tabular learning {cpu_tabular:,.0f} turns/s")
    if device == "cpu":
        print("no GPU here: the CPU alone was measured (below, it stands for the device)")
        project(cpu, cpu_eval, cpu_tabular, args)
        return
    print(f"{devices.describe(device)}:")
    gpu = measure(device, args, args.rounds, [t for t in args.tasks if t < here] or [1])
    for r in cpu_rounds:
        print(f"  {r:2d} rounds: {gpu['match'][r] / cpu['match'][r]:.1f}x the CPU")
    for name, rate in gpu["dsn"].items():
        print(f"  DSN {name}: {rate / cpu['dsn'][name]:.1f}x the CPU")
    project(gpu, cpu_eval, cpu_tabular, args)


if __name__ == "__main__":
    main()
