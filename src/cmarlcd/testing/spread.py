"""The compiled simple_spread held against ``mpe2`` (1.1.1, the ``[test]`` extra): step for
step from the same state and actions, and its resets by distribution.

* :func:`compare_steps`: both games side by side. At every reset mpe2 draws the episode
  and its positions are copied into the compiled game; then both take the same uniform
  random actions, and every observation, each agent's reward and the episode's end must
  agree within ``tolerance`` (1e-5) at every step.
* :func:`compare_resets`: both games reset ``count`` times each with their own
  generators; a two-sample Kolmogorov-Smirnov test per coordinate (each agent's and each
  landmark's x and y), Bonferroni-corrected.

``benchmarks/check_spread.py`` runs both at full length; ``tests/games/test_spread.py`` a
short form.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from cmarlcd.errors import ConfigError
from cmarlcd.games.spread import kernels as k
from cmarlcd.games.spread.rules import SimpleSpread
from cmarlcd.testing.resets import ResetReport

#: The largest difference the check accepts, per number and step.
TOLERANCE = 1e-5


def package_env(rules: SimpleSpread):
    """mpe2's ``simple_spread_v3`` parallel env with the same rules."""
    try:
        from mpe2 import simple_spread_v3
    except ImportError:
        raise ConfigError(
            "mpe2", "the check needs the package: pip install -e '.[test]' (mpe2 1.1.1)"
        ) from None
    return simple_spread_v3.parallel_env(**rules.package_kwargs())


def copy_state(package, env: tuple) -> None:
    """mpe2's positions and velocities into the compiled game's arrays."""
    world = package.unwrapped.world
    for i, agent in enumerate(world.agents):
        env[0][i, k.X], env[0][i, k.Y] = agent.state.p_pos
        env[0][i, k.VX], env[0][i, k.VY] = agent.state.p_vel
    for m, landmark in enumerate(world.landmarks):
        env[1][m] = landmark.state.p_pos


@dataclass
class StepReport:
    """What :func:`compare_steps` found."""

    task: str
    steps: int = 0
    episodes: int = 0
    largest_difference: float = 0.0
    collisions: int = 0
    """Steps on which some agent was penalised for a collision."""
    mismatches: list[str] = field(default_factory=list)

    @property
    def equal(self) -> bool:
        return not self.mismatches


def compare_steps(
    rules: SimpleSpread, steps: int, seed: int = 0, tolerance: float = TOLERANCE
) -> StepReport:
    """Play ``steps`` steps of both games (see the module docstring)."""
    package = package_env(rules)
    env = rules.new_env()
    names = [f"agent_{i}" for i in range(rules.N)]
    rng = np.random.default_rng(seed)
    report = StepReport(rules.name)
    team, joint = np.zeros(1), np.zeros(rules.N, dtype=np.int64)
    features = np.zeros(rules.spec().n_features, dtype=np.float32)
    observations, _ = package.reset(seed=seed)
    copy_state(package, env)
    report.episodes, length = 1, 0
    while report.steps < steps and len(report.mismatches) < 5:
        joint[:] = rng.integers(k.N_ACTIONS, size=rules.N)
        observations, rewards, terminations, truncations, _ = package.step(
            {name: int(a) for name, a in zip(names, joint, strict=True)}
        )
        k.spread_step(env, joint, rng, team)
        report.steps, length = report.steps + 1, length + 1
        k.spread_features(env, 0, features)
        theirs = np.concatenate([observations[name] for name in names])
        gaps = [float(np.abs(features - theirs).max())]
        gaps += [abs(env[4][i] - rewards[name]) for i, name in enumerate(names)]
        gaps.append(abs(team[0] - sum(rewards[name] for name in names)))
        report.largest_difference = max(report.largest_difference, *gaps)
        report.collisions += int(any(rewards[n] != rewards[names[0]] for n in names))
        ended = length >= rules.max_cycles or bool(k.spread_done(env))
        package_ended = all(truncations.values()) or all(terminations.values())
        where = f"step {report.steps} (episode {report.episodes})"
        if max(gaps) > tolerance:
            report.mismatches.append(f"{where}: a difference of {max(gaps):.3g}")
        if ended != package_ended or any(terminations.values()):
            report.mismatches.append(f"{where}: ended {ended} against the package's")
        if package_ended:
            observations, _ = package.reset()
            copy_state(package, env)
            report.episodes, length = report.episodes + 1, 0
    return report


def compare_resets(
    rules: SimpleSpread, count: int, seed: int = 0, alpha: float = 0.001
) -> ResetReport:
    """``count`` resets of each game, coordinate by coordinate (see the module
    docstring)."""
    env, rng = rules.new_env(), np.random.default_rng(seed)
    ours = np.zeros((count, 4 * rules.N))
    for r in range(count):
        k.spread_reset(env, rng)
        ours[r] = np.concatenate([env[0][:, :2].ravel(), env[1].ravel()])
    package = package_env(rules)
    package.reset(seed=seed + 1)
    world = package.unwrapped.world
    theirs = np.zeros_like(ours)
    for r in range(count):
        package.reset()
        places = [a.state.p_pos for a in world.agents] + [m.state.p_pos for m in world.landmarks]
        theirs[r] = np.concatenate(places)
    labels = [f"agent {i} {axis}" for i in range(rules.N) for axis in "xy"]
    labels += [f"landmark {m} {axis}" for m in range(rules.N) for axis in "xy"]
    p_values = {
        label: float(stats.ks_2samp(ours[:, c], theirs[:, c]).pvalue)
        for c, label in enumerate(labels)
    }
    return ResetReport(rules.name, count, p_values, alpha)
