"""Benchmark: ``cmarl-cd train``'s loop over copies of a PettingZoo environment.

Measures, in one run on this machine: the bare environment stepped with uniform random
actions (one copy, no learner: the rate a learner cannot beat on one core), then a
learner with its default settings learning through :func:`cmarlcd.training.episodes.play_copies`
at each ``--envs`` count (environment steps per second, gradient steps included), with
the ratio of each to the bare rate and the share of the time spent in the
environment's ``step``, in the learner's acting and in its gradient steps (``td_step``
or ``learn``). The shares overlap: VDN and QMIX take their gradient steps inside
``act``, when a pending transition is completed, so their acting share includes them.

Usage: python benchmarks/bench_env_copies.py [--env MODULE:FACTORY] [--env-kwargs JSON]
           [--learner vdn] [--episodes 200] [--envs 1 4 16 64]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments import environment as envs
from cmarlcd.training.episodes import play_copies

MPE = "mpe2.simple_spread_v3:parallel_env"


class Timed:
    """A wrapper that adds up the seconds spent in one method of an object."""

    def __init__(self, target, name: str, clock: dict) -> None:
        self.target, self.name, self.clock = target, name, clock

    def __getattr__(self, attribute):
        value = getattr(self.target, attribute)
        if attribute != self.name:
            return value

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return value(*args, **kwargs)
            finally:
                self.clock[self.name] = self.clock.get(self.name, 0.0) + time.perf_counter() - start

        return timed


def bare_rate(args, kwargs) -> float:
    """Environment steps per second with uniform random actions, one copy."""
    env = envs.make_env(args.env, kwargs)
    rng, steps, start = np.random.default_rng(0), 0, time.perf_counter()
    for episode in range(args.episodes):
        env.reset(seed=episode)
        while env.agents:
            env.step({a: int(rng.integers(env.action_space(a).n)) for a in env.agents})
            steps += 1
    return steps / (time.perf_counter() - start)


def learning(args, kwargs, copies: int) -> tuple[float, dict]:
    """(environment steps per second, seconds in step / act / learn) for ``copies``."""
    seeds = envs.copy_seeds(np.random.SeedSequence(0), copies)
    made = envs.make_copies(args.env, kwargs, "state", copies)
    shape, counts = envs.check_copies(made, "state", seeds)
    config = registry.require_learner(args.learner)
    episodes = args.episodes * max(1, copies // 4)
    learner = envs.new_learner(config, counts, shape, episodes, np.random.SeedSequence(1))
    clock: dict[str, float] = {}
    for env in made:  # the environments' step, timed in place
        env.step = Timed(env, "step", clock).__getattr__("step")
    model = learner.model
    for name in ("td_step", "learn"):  # VDN and QMIX step by td_step, deep CMARL-CD by learn
        if hasattr(model, name):
            setattr(model, name, Timed(model, name, clock).__getattr__(name))
    start = time.perf_counter()
    stats = play_copies(made, Timed(learner, "act_many" if copies > 1 else "act", clock),
                        episodes, seeds=seeds, global_reward=envs.REWARDS["sum"])  # fmt: skip
    wall = time.perf_counter() - start
    return stats.lengths.sum() / wall, {k: v / wall for k, v in clock.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default=MPE)
    parser.add_argument("--env-kwargs", default='{"continuous_actions": false}')
    parser.add_argument("--learner", default="vdn")
    parser.add_argument("--episodes", type=int, default=200, help="episodes per 4 copies")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 4, 16, 64])
    args = parser.parse_args()
    kwargs = tuple(sorted(json.loads(args.env_kwargs).items()))
    import torch

    threads = os.environ.get("OMP_NUM_THREADS")
    print(f"{platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
          f"OMP_NUM_THREADS={threads}; {args.env} {args.env_kwargs}")  # fmt: skip
    bare = bare_rate(args, kwargs)
    print(f"bare environment, random actions: {bare:,.0f} steps/s")
    for copies in args.envs:
        rate, shares = learning(args, kwargs, copies)
        spent = ", ".join(f"{k} {100 * v:.0f} %" for k, v in sorted(shares.items()))
        print(f"{args.learner} --envs {copies:3d}: {rate:8,.0f} steps/s = {rate / bare:.2f}x bare"
              f" (time in {spent})", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
