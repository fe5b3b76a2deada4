"""simple_spread returns on the scale of the EPyMARL benchmark paper, checked on the
random policy.

The EPyMARL paper (Papoudakis et al., 2021) trains on ``mpe:SimpleSpread-v0``, a fork of
OpenAI's particle environments, and reports returns divided by the number of agents.
Per step, with ``D`` the sum over landmarks of the nearest agent's distance and ``P`` the
number of colliding agent pairs:

* the fork: agent i earns ``-D - 1 - k_i`` (``k_i`` the others touching it; the ``-1`` is
  its collision with itself, which the fork counts), the reward is shared (each agent
  gets the sum, ``-3D - 3 - 2P``) and EPyMARL sums the three copies; divided by 3 the
  step adds ``-3D - 3 - 2P``;
* PettingZoo's / mpe2's ``simple_spread_v3`` with ``local_ratio=0.5``: agent i earns
  ``-D/2 - k_i/2``, so cmarl-cd's team reward (``--reward sum``) is ``-1.5D - P``.

Over 25 steps, therefore: **EPyMARL-scale return = 2 x team return - 75.** This script
checks that identity episode by episode on the random policy, computing the fork's
reward from the environment's positions, and prints the random policy's return on both
scales:

    python benchmarks/epymarl_scale.py --episodes 1000
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

STEPS = 25


def to_epymarl(team_return: float) -> float:
    """cmarl-cd's team return on simple_spread_v3 (3 agents, local_ratio 0.5, 25 steps,
    ``--reward sum``) on the EPyMARL paper's scale."""
    return 2.0 * team_return - 3.0 * STEPS


def fork_step_reward(world) -> float:
    """The step's EPyMARL-scale reward from the positions: the shared reward of OpenAI's
    simple_spread (self-collision included), summed over agents and divided by them."""
    agents, landmarks = world.agents, world.landmarks
    nearest = sum(
        min(np.linalg.norm(a.state.p_pos - lm.state.p_pos) for a in agents) for lm in landmarks
    )
    total = 0.0
    for agent in agents:
        touching = sum(
            np.linalg.norm(a.state.p_pos - agent.state.p_pos) < a.size + agent.size for a in agents
        )
        total += -nearest - touching
    return total


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--episodes", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    if args.episodes < 1:
        print("error: --episodes must be >= 1", file=sys.stderr)
        return 2
    from mpe2 import simple_spread_v3

    env = simple_spread_v3.parallel_env(N=3, local_ratio=0.5, max_cycles=STEPS,
                                        continuous_actions=False)  # fmt: skip
    rng = np.random.default_rng(args.seed)
    team, fork = [], []
    for episode in range(args.episodes):
        env.reset(seed=args.seed * 1_000_003 + episode)
        team_return = fork_return = 0.0
        while env.agents:
            actions = {a: int(rng.integers(5)) for a in env.agents}
            _, rewards, *_ = env.step(actions)
            team_return += sum(rewards.values())
            fork_return += fork_step_reward(env.unwrapped.world)
        team.append(team_return)
        fork.append(fork_return)
    team_a, fork_a = np.array(team), np.array(fork)
    worst = float(np.max(np.abs(fork_a - np.vectorize(to_epymarl)(team_a))))
    sem = lambda x: x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else 0.0  # noqa: E731
    print(f"random policy, {args.episodes} episodes of simple_spread_v3 (mpe2):")
    print(f"  team return (cmarl-cd, reward sum): {team_a.mean():9.2f} ± {sem(team_a):.2f} (SE)")
    print(f"  EPyMARL scale, from the positions:  {fork_a.mean():9.2f} ± {sem(fork_a):.2f} (SE)")
    print(f"  2 x team - 75:                      {to_epymarl(team_a.mean()):9.2f}")
    print(f"  largest per-episode difference from the identity: {worst:.2e}")
    return 0 if worst < 1e-6 else 1


if __name__ == "__main__":
    sys.exit(main())
