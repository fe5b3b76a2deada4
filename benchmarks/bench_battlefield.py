"""Benchmark: matches of the blood battlefield (Section V-B, Figs. 6-7).

Prints
  * learning turns/s of a CMARL-CD vs LA-OCA match through the compiled match loop and
    through the generic PettingZoo ParallelEnv loop (object-API learners), on the same
    episodes (same seeds, so the very same turns), and their ratio;
  * learning and evaluation turns/s of one match of each kind of pairing (tabular-tabular,
    tabular-deep, deep-deep), a deep pairing's learning alone (B = 1) and with B rounds
    learning together (the tournament's --seed-batch), and from them the projected wall
    time of the paper's protocol (30 rounds x 10 matches x (500k + 500k) episodes) on
    this machine's workers, and the states each deep side's greedy cache holds after
    the evaluation;
  * the peak memory (max RSS of a fresh process) of one tabular match at the paper's
    500,000 learning episodes, CMARL-CD against itself (the largest tables), unless
    --no-memory.

Usage: python benchmarks/bench_battlefield.py [--episodes E] [--deep-episodes D]
       [--batch B] [--workers N] [--step autograd|fused] [--no-memory]

``--step fused`` times the deep learners with the fused CPU gradient step
(``DeepConfig.step``) instead of autograd's.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np

from cmarlcd.experiments import tournament as tour
from cmarlcd.games import battlefield
from cmarlcd.learners.deep.config import STEPS
from cmarlcd.learners.tabular.automata import LAOCA
from cmarlcd.learners.tabular.coordination import CMARLCDStochastic
from cmarlcd.sweeps.runner import default_workers
from cmarlcd.training.deep_kernels import GENERATION, GREEDY_CACHE_SLOTS
from cmarlcd.training.match import Match, MatchBatch

LEARNERS = tour.battlefield_learners()
SIDE = 6


def rngs() -> tuple[np.random.Generator, tuple[np.random.Generator, np.random.Generator]]:
    return np.random.default_rng(0), (np.random.default_rng(1), np.random.default_rng(2))


def new_match(a: str, b: str, episodes: int) -> Match:
    env, sides = rngs()
    return Match(battlefield.SPEC, (LEARNERS[a], LEARNERS[b]), env, sides, episodes)


def cached_states(played: Match) -> list[int]:
    """States each deep side of ``played`` holds greedy actions for, computed with its
    current weights (:class:`cmarlcd.training.deep_kernels.GreedyCache`)."""
    held = []
    for side in played.sides:
        cache = getattr(side.data, "cache", None)
        if cache is not None and cache.keys.size:
            generation = side.data.counters[GENERATION]
            held.append(int(((cache.keys >= 0) & (cache.generations == generation)).sum()))
    return held


def compiled_turns(
    a: str, b: str, episodes: int, evaluate: bool
) -> tuple[float, float, int, list[int]]:
    """(learning turns/s, evaluation turns/s, learning turns, the states each deep side's
    greedy cache holds after the evaluation) of one match."""
    # compile (or load the cache); a deep side's first gradient step comes once its
    # replay holds a batch (720 transitions: about 110 episodes)
    deep = not {a, b} <= set(tour.TABULAR)
    warm = new_match(a, b, 200 if deep else 2)
    warm.learn()
    warm.evaluate(2, np.random.default_rng(3))
    played = new_match(a, b, episodes)
    start = time.perf_counter()
    played.learn()
    learn = played.turns / (time.perf_counter() - start)
    if not evaluate:
        return learn, float("nan"), played.turns, []
    start = time.perf_counter()
    result = played.evaluate(episodes, np.random.default_rng(3))
    evaluation = result.turns / (time.perf_counter() - start)
    return learn, evaluation, played.turns, cached_states(played)


def batched_learning_turns(a: str, b: str, episodes: int, batch: int) -> float:
    """Learning turns/s of ``batch`` matches of one pairing learning together."""
    positions = [(0, 1) if r % 2 == 0 else (1, 0) for r in range(batch)]
    streams = [np.random.default_rng(r).spawn(3) for r in range(batch)]
    envs = [env for env, _, _ in streams]
    sides = [(s0, s1) for _, s0, s1 in streams]
    pair = (LEARNERS[a], LEARNERS[b])
    MatchBatch(battlefield.SPEC, pair, positions, envs, sides, 2).learn()  # compile
    played = MatchBatch(battlefield.SPEC, pair, positions, envs, sides, episodes)
    start = time.perf_counter()
    played.learn()
    return sum(m.turns for m in played.matches) / (time.perf_counter() - start)


def parallel_env_turns(episodes: int) -> tuple[float, int]:
    """The generic loop: object-API learners on the ParallelEnv, one side each."""
    counts = [SIDE] * SIDE
    _, (a, b) = rngs()
    learners = [
        CMARLCDStochastic(counts, LEARNERS["cmarl-cd"], seed=a),
        LAOCA(counts, LEARNERS["la-oca"], seed=b),
    ]
    env = battlefield.BattlefieldEnv()
    env.np_random = np.random.default_rng(0)
    names = [env.possible_agents[:SIDE], env.possible_agents[SIDE:]]
    turns, start = 0, time.perf_counter()
    for _ in range(episodes):
        _, infos = env.reset()
        while env.agents:
            states = [env.state(0), env.state(1)]
            joints = [
                learner.act(state, [infos[agent]["action_mask"] for agent in side])
                for learner, state, side in zip(learners, states, names, strict=True)
            ]
            actions = dict(zip(env.possible_agents, joints[0] + joints[1], strict=True))
            _, rewards, terminations, _, infos = env.step(actions)
            turns += 1
            for k, learner in enumerate(learners):
                learner.observe(states[k], joints[k], rewards[names[k][0]])
        for k, learner in enumerate(learners):
            learner.end_episode(env.state(k), any(terminations.values()))
    return turns / (time.perf_counter() - start), turns


def peak_memory_mb(episodes: int) -> float:
    """Peak RSS of one CMARL-CD self-play match in a fresh process, compilation excluded
    (the peak is reset, Linux /proc/self/clear_refs, after a two-episode warm-up)."""
    code = (
        "import numpy as np\n"
        "from cmarlcd.experiments.tournament import battlefield_learners\n"
        "from cmarlcd.games import battlefield\n"
        "from cmarlcd.training.match import Match\n"
        "c = battlefield_learners()['cmarl-cd']\n"
        "def match(n):\n"
        "    r = [np.random.default_rng(k) for k in range(4)]\n"
        "    m = Match(battlefield.SPEC, (c, c), r[0], r[1:3], n)\n"
        "    m.learn(); m.evaluate(1000, r[3]); return m\n"
        "def status(key):\n"
        "    line = [x for x in open('/proc/self/status') if x.startswith(key)][0]\n"
        "    return int(line.split()[1]) // 1024\n"
        "match(2); base = status('VmRSS')\n"
        "open('/proc/self/clear_refs', 'w').write('5')\n"
        f"m = match({episodes})\n"
        "print(m.visited(0), m.visited(1), m.memory_bytes(), base, status('VmHWM'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    visited_0, visited_1, table_bytes, base, peak = map(int, out.stdout.split())
    print(
        f"memory: one CMARL-CD self-play match of {episodes:,} learning episodes visits "
        f"{visited_0:,} and {visited_1:,} of the 802,816 states per side; tables "
        f"{table_bytes / 2**20:,.0f} MiB; peak RSS {peak:,} MiB ({base:,} MiB before the "
        "match: Python, numba, the compiled loops)"
    )
    return float(peak)


PAIRINGS = {  # matches of each kind in a round of the paper's four algorithms
    ("cmarl-cd", "la-oca"): 3,  # the three tabular matches (timed as this one)
    ("cmarl-cd", "vdn"): 2,  # CMARL-CD and LA-OCA against VDN
    ("cmarl-cd", "qmix"): 2,
    ("vdn", "vdn"): 1,
    ("qmix", "qmix"): 1,
    ("qmix", "vdn"): 1,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20_000, help="tabular match episodes")
    parser.add_argument("--deep-episodes", type=int, default=5_000, help="deep match episodes")
    parser.add_argument("--python-episodes", type=int, default=500)
    parser.add_argument("--batch", type=int, default=tour.SEED_BATCH, help="rounds together")
    parser.add_argument("--workers", type=int, default=default_workers())
    parser.add_argument("--no-memory", action="store_true")
    parser.add_argument("--step", choices=STEPS, default="autograd", help="deep gradient step")
    args = parser.parse_args()
    for name in ("vdn", "qmix"):
        LEARNERS[name] = replace(LEARNERS[name], step=args.step)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; workers: {args.workers}; deep step: {args.step}"
    )
    fast, _, fast_turns, _ = compiled_turns("cmarl-cd", "la-oca", args.python_episodes, False)
    slow, slow_turns = parallel_env_turns(args.python_episodes)
    assert fast_turns == slow_turns, "both paths must play the same turns"
    print(
        f"CMARL-CD vs LA-OCA learning, {args.python_episodes:,} episodes = {fast_turns:,} "
        f"turns: compiled {fast:,.0f} turns/s, ParallelEnv loop {slow:,.0f} turns/s, "
        f"ratio {fast / slow:,.0f}x"
    )
    alone_seconds = batched_seconds = 0.0
    for (a, b), count in PAIRINGS.items():
        deep = "vdn" in (a, b) or "qmix" in (a, b)
        episodes = args.deep_episodes if deep else args.episodes
        learn, evaluate, turns, held = compiled_turns(a, b, episodes, True)
        per_episode = turns / episodes
        batched = batched_learning_turns(a, b, episodes, args.batch) if deep else learn
        turns_per_stage = tour.PAPER_LEARN_EPISODES * per_episode
        alone = turns_per_stage * (1 / learn + 1 / evaluate)
        together = turns_per_stage * (1 / batched + 1 / evaluate)
        alone_seconds += count * alone
        batched_seconds += count * together
        print(
            f"{a} vs {b}: {episodes:,} episodes, {per_episode:.2f} turns each; learning "
            f"{learn:,.0f} turns/s alone, {batched:,.0f} turns/s with {args.batch} rounds "
            f"together ({batched / learn:.1f}x); evaluation {evaluate:,.0f} turns/s; a paper "
            f"match (500k + 500k episodes) ~ {alone / 60:.1f} min alone, "
            f"{together / 60:.1f} min batched"
        )
        if held:
            print(
                f"  greedy cache after the evaluation: {' and '.join(f'{n:,}' for n in held)} "
                f"states held (of {GREEDY_CACHE_SLOTS:,} slots a side)"
            )
    for label, seconds in (("alone", alone_seconds), ("batched", batched_seconds)):
        total = tour.PAPER_ROUNDS * seconds / args.workers
        print(
            f"projected paper protocol (30 rounds x 10 matches), {args.workers} workers, "
            f"matches {label}: {total / 3600:.1f} h ({seconds / 60:.0f} min of matches per round)"
        )
    if not args.no_memory:
        peak_memory_mb(tour.PAPER_LEARN_EPISODES)


if __name__ == "__main__":
    main()
