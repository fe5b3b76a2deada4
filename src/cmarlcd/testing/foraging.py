"""The compiled Level-Based Foraging game held against the ``lbforaging`` package (2.0.0,
the ``[test]`` extra): step for step from the same state and actions, and its resets by
distribution.

* :func:`compare_steps`: both games played side by side. At every reset the package
  draws the episode and its state (agents' cells and levels, the foods, the step count)
  is copied into the compiled game; then both take the same actions, and the
  observations, each agent's reward, the team's reward and the episode's end (the
  package's ``done`` against the compiled game's ``done`` or its step cap) must be
  *exactly* equal at every step.
* :func:`compare_resets`: both games reset ``count`` times each, every one with its own
  generator; a two-sample chi-square test per statistic (each agent's cell and level,
  the foods placed, their levels summed, the first and the last food's cell, and
  whether an agent starts where it started last time, which the package's quirk
  forbids), Bonferroni-corrected.

``benchmarks/check_foraging.py`` runs both at full length; ``tests/games/test_foraging.py``
a short form.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from cmarlcd.errors import ConfigError
from cmarlcd.games.foraging import kernels as k
from cmarlcd.games.foraging.rules import Foraging
from cmarlcd.testing.resets import ResetReport

#: [choice] The chance that an agent of the check's random policy tries LOAD (otherwise a
#: uniform action of the six): loads are what the rules are mostly about, and a uniform
#: policy makes few next to a food.
LOAD_CHANCE = 0.3


def package_env(rules: Foraging):
    """The package's ``ForagingEnv`` with the same rules."""
    try:
        from lbforaging.foraging import ForagingEnv
    except ImportError:
        raise ConfigError(
            "lbforaging", "the check needs the package: pip install -e '.[test]' (lbforaging 2.0.0)"
        ) from None
    return ForagingEnv(**rules.package_kwargs())


def copy_state(package, env: tuple) -> None:
    """The package's state (agents, foods, step) into the compiled game's arrays."""
    players, field_, _, status, _, _ = env
    for i, player in enumerate(package.players):
        players[i, k.ROW], players[i, k.COL] = player.position
        players[i, k.LEVEL] = player.level
    field_[:] = package.field
    status[k.STEP] = package.current_step
    status[k.FOOD_SPAWNED] = int(package._food_spawned)
    status[k.OVER] = bool(package._game_over)


def observations(env: tuple, players: int, width: int) -> np.ndarray:
    """Every agent's observation by the compiled game, (players, width) float32."""
    out = np.zeros(players * width, dtype=np.float32)
    k.forage_features(env, 0, out)
    return out.reshape(players, width)


@dataclass
class StepReport:
    """What :func:`compare_steps` found."""

    task: str
    steps: int = 0
    episodes: int = 0
    loads: int = 0
    """Steps on which a food was collected."""
    failed_loads: int = 0
    """Steps on which some agent got the penalty (a load short of the food's level)."""
    mismatches: list[str] = field(default_factory=list)
    """The first differences found, one line each (empty: equal)."""

    @property
    def equal(self) -> bool:
        return not self.mismatches


def compare_steps(
    rules: Foraging, steps: int, seed: int = 0, max_mismatches: int = 5
) -> StepReport:
    """Play ``steps`` steps of both games from the same states and actions (see the module
    docstring); a report of what differed."""
    package = package_env(rules)
    env = rules.new_env()
    n, width = rules.players, rules.observation_size
    rng = np.random.default_rng(seed)
    report = StepReport(rules.name)
    team = np.zeros(1)
    joint = np.zeros(n, dtype=np.int64)
    expected, _ = package.reset(seed=seed)
    copy_state(package, env)
    report.episodes = 1
    _check_observations(report, expected, observations(env, n, width), "reset")
    while report.steps < steps and len(report.mismatches) < max_mismatches:
        for i in range(n):
            joint[i] = k.LOAD if rng.random() < LOAD_CHANCE else int(rng.integers(k.N_ACTIONS))
        before = package.field.sum()
        expected, rewards, done, truncated, _ = package.step(joint.tolist())
        k.forage_step(env, joint, rng, team)
        report.steps += 1
        where = f"step {report.steps} (episode {report.episodes}, actions {joint.tolist()})"
        _check_observations(report, expected, observations(env, n, width), where)
        ours = env[4][:n].tolist()
        if ours != [float(r) for r in rewards]:
            report.mismatches.append(f"{where}: rewards {ours} against the package's {rewards}")
        if team[0] != sum(float(r) for r in rewards):
            report.mismatches.append(f"{where}: team reward {team[0]} against {sum(rewards)}")
        over = bool(k.forage_done(env)) or env[3][k.STEP] >= rules.max_steps
        if over != bool(done) or truncated:
            report.mismatches.append(f"{where}: over {over} against the package's {done}")
        report.loads += int(package.field.sum() < before)
        report.failed_loads += int(any(r < 0 for r in rewards))
        if done:
            expected, _ = package.reset()
            copy_state(package, env)
            report.episodes += 1
            _check_observations(report, expected, observations(env, n, width), "a reset")
    return report


def _check_observations(report: StepReport, expected, ours: np.ndarray, where: str) -> None:
    for i, observation in enumerate(expected):
        if not np.array_equal(np.asarray(observation, dtype=np.float32), ours[i]):
            report.mismatches.append(
                f"{where}: agent {i} observes {ours[i].tolist()}, the package "
                f"{np.asarray(observation).tolist()}"
            )


# ------------------------------------------------------------------------- resets


def _reset_statistics(players: np.ndarray, field_: np.ndarray, previous: np.ndarray) -> dict:
    """The category one reset falls in, by statistic: one value each, so that the
    resets are the independent samples the chi-square test takes (the foods of one
    reset are not independent of one another)."""
    cols = field_.shape[1]
    cells = players[:, k.ROW] * cols + players[:, k.COL]
    foods = np.flatnonzero(field_)
    found = {f"agent {i} cell": int(c) for i, c in enumerate(cells)}
    found |= {f"agent {i} level": int(players[i, k.LEVEL]) for i in range(len(players))}
    found["foods placed"] = len(foods)
    found["food levels summed"] = int(field_.sum())
    found["first food's cell (row-major)"] = int(foods[0]) if len(foods) else -1
    found["last food's cell"] = int(foods[-1]) if len(foods) else -1
    found["an agent where it started last time"] = int(bool(np.any(cells == previous)))
    return found


def _tally(resets) -> dict[str, dict[int, int]]:
    counts: dict[str, dict[int, int]] = {}
    previous = None
    for players, field_ in resets:
        cells = players[:, k.ROW] * field_.shape[1] + players[:, k.COL]
        last = np.full_like(cells, -1) if previous is None else previous
        for name, value in _reset_statistics(players, field_, last).items():
            table = counts.setdefault(name, {})
            table[value] = table.get(value, 0) + 1
        previous = cells
    return counts


def _package_resets(rules: Foraging, count: int, seed: int):
    package = package_env(rules)
    package.reset(seed=seed)
    for _ in range(count):
        package.reset()
        players = np.array(
            [[*p.position, p.level] for p in package.players], dtype=np.int64
        ).reshape(-1, 3)
        yield players, package.field.copy()


def _compiled_resets(rules: Foraging, count: int, seed: int):
    env = rules.new_env()
    rng = np.random.default_rng(seed)
    k.forage_reset(env, rng)
    for _ in range(count):
        k.forage_reset(env, rng)
        yield env[0].copy(), env[1].copy()


def compare_resets(rules: Foraging, count: int, seed: int = 0, alpha: float = 0.001) -> ResetReport:
    """``count`` resets of each game, compared statistic by statistic (see the module
    docstring): a two-sample chi-square test of homogeneity over the categories both
    saw (a statistic constant in both has p = 1)."""
    ours = _tally(_compiled_resets(rules, count, seed))
    theirs = _tally(_package_resets(rules, count, seed + 1))
    p_values = {}
    for name in sorted(set(ours) | set(theirs)):
        a, b = ours.get(name, {}), theirs.get(name, {})
        categories = sorted(set(a) | set(b))
        table = np.array([[a.get(c, 0) for c in categories], [b.get(c, 0) for c in categories]])
        if len(categories) < 2:
            p_values[name] = 1.0
            continue
        p_values[name] = float(stats.chi2_contingency(table, correction=False).pvalue)
    return ResetReport(rules.name, count, p_values, alpha)
