"""Conformance of a learner: what every loop of the package relies on, checked on the tiny
games of :mod:`cmarlcd.testing.games`.

:func:`check_learner` takes a learner's config, as the registry holds it, and runs the
checks of its kind (it raises ``AssertionError`` at the first failure):

* a repeated-game learner (a config with
  :class:`~cmarlcd.learners.tabular.protocol.RepeatedKernels`): the object API learns
  exactly what the compiled loop learns from the same stream; the same seed gives the
  same run; it finds the optimum of a trivial game in 9 runs of 10;
* a tabular learner for stochastic games
  (:class:`~cmarlcd.learners.tabular.protocol.TabularConfig`): the compiled loop learns
  exactly what the object API learns on the game's ``ParallelEnv``; the same seeds give
  the same tables; its greedy policy keeps to the legal actions, whatever numbers its
  tables hold; it plays either side of a two-team game, learning and evaluating;
* a deep learner (:class:`~cmarlcd.learners.deep.config.DeepConfig`, the ``[deep]`` extra):
  a seed trained in a stacked batch learns what it learns alone; its greedy policy keeps
  to the legal actions; it plays either side of a two-team game from state features.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from cmarlcd.games.env import KernelParallelEnv
from cmarlcd.games.matrix import from_payoffs
from cmarlcd.games.spec import GameSpec
from cmarlcd.learners.deep.config import DeepConfig, DeepLearnerConfig
from cmarlcd.learners.tabular.independent import RepeatedLearner
from cmarlcd.learners.tabular.protocol import (
    RepeatedKernels,
    TabularConfig,
    TabularLearner,
    greedy_policy,
)
from cmarlcd.testing.games import CHAIN, DUEL
from cmarlcd.training import TabularRun, play_episodes
from cmarlcd.training.match import Match
from cmarlcd.training.repeated import play_until_converged

#: A repeated game with one optimal joint action (1) and nothing else to find (0); the
#: optimum is not the lowest-index joint action, which a learner that learns nothing picks.
TRIVIAL_PAYOFFS = [[0.0, 0.0], [0.0, 1.0]]
#: [choice] Runs on the trivial game, of which all but one must end on its optimum (a
#: learner may lock in early by chance: CMARL-CD's max-reward indicator can settle on a
#: joint action of payoff 0 before the optimum is ever played).
TRIVIAL_RUNS = 10


def check_learner(config: Any, episodes: int = 300) -> None:
    """Every check of ``config``'s kind (see the module docstring)."""
    if isinstance(getattr(config, "kernels", None), RepeatedKernels):
        check_repeated_learner(config)
    elif isinstance(config, TabularConfig):
        check_tabular_learner(config, episodes)
    elif isinstance(config, DeepLearnerConfig):
        check_deep_learner(config, episodes)
    else:
        raise AssertionError(f"{config!r} is no learner config this package knows")


# ---------------------------------------------------------------- repeated games


def check_repeated_learner(config: Any, games: int = 2_000) -> None:
    """The object API against the compiled loop, determinism, a trivial game solved."""
    game = from_payoffs([[5.0, 0.0, 1.0], [0.0, 3.0, 0.0], [1.0, 0.0, 4.0]])
    stepped = RepeatedLearner(config, game.action_counts, seed=7)
    played = _play_step_by_step(stepped, game, games)
    compiled = RepeatedLearner(config, game.action_counts, seed=7)
    loop = _compiled(play_until_converged, game, config)
    ran, _ = loop(
        game.new_env(), compiled.tables, compiled.params, compiled.counts, games, compiled.rng
    )
    assert ran == played, f"{config.name}: the compiled loop played {ran} games, the API {played}"
    _assert_same_tables(stepped.tables, compiled.tables, config.name)
    again = RepeatedLearner(config, game.action_counts, seed=7)
    _play_step_by_step(again, game, games)
    _assert_same_tables(stepped.tables, again.tables, config.name + " (same seed)")
    trivial = from_payoffs(TRIVIAL_PAYOFFS)
    found = 0
    for seed in range(TRIVIAL_RUNS):
        learner = RepeatedLearner(config, trivial.action_counts, seed=seed)
        _play_step_by_step(learner, trivial, games)
        found += trivial.is_optimal(learner.greedy_joint_action())
    assert found >= TRIVIAL_RUNS - 1, f"{config.name} found the optimum in {found} of 10 runs"


def _play_step_by_step(learner: RepeatedLearner, game, games: int) -> int:
    """Algorithm 1's loop through the object API; the games played until convergence."""
    for played in range(1, games + 1):
        joint = learner.act()
        changed = learner.update(joint, game.payoff(joint))
        if changed and learner.kernels.converged(learner.tables, learner.params, learner.counts):
            return played
    return games


def _compiled(template, game, config):
    from cmarlcd.compiled import specialise

    return specialise(template, game=game.spec().kernels, learner=config.kernels)


def _assert_same_tables(ours: tuple, theirs: tuple, what: str) -> None:
    for name, a, b in zip(ours._fields, ours, theirs, strict=True):  # type: ignore[attr-defined]
        assert np.array_equal(a, b), f"{what}: tables.{name} differ"


# ---------------------------------------------------------- tabular, stochastic


def check_tabular_learner(config: TabularConfig, episodes: int = 300) -> None:
    """Compiled loop = object API on the ParallelEnv; determinism; legal greedy
    actions; both sides of a two-team game."""
    learner = TabularLearner(CHAIN.action_counts, config, n_states=CHAIN.n_states, seed=22)
    stats = play_episodes(KernelParallelEnv(CHAIN), learner, episodes, seed=11)
    run = TabularRun(CHAIN, config, np.random.default_rng(11), np.random.default_rng(22))
    steps = run.train(episodes)
    assert steps == int(stats.lengths.sum()), f"{config.name}: {steps} steps compiled"
    _assert_same_tables(learner.tables, run.tables, f"{config.name}: compiled vs object API")
    again = TabularRun(CHAIN, config, np.random.default_rng(11), np.random.default_rng(22))
    again.train(episodes)
    _assert_same_tables(run.tables, again.tables, f"{config.name} (same seeds)")
    _assert_legal(run.greedy_policy(), run.seen, CHAIN, config.name)
    _assert_greedy_legal_whatever_the_values(config, run)
    _check_two_team_play(config, episodes)


def _assert_greedy_legal_whatever_the_values(config: TabularConfig, run: TabularRun) -> None:
    """The greedy rule keeps to the recorded masks whatever the learned numbers: every
    float table is filled at random, again and again, and the greedy joint action of
    every visited state checked."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        tables = type(run.tables)(
            *(rng.normal(size=a.shape) if a.dtype.kind == "f" else a.copy() for a in run.tables)
        )
        policy = greedy_policy(config, tables, run.counts)
        _assert_legal(policy, run.seen, CHAIN, f"{config.name} (random values)")


def _assert_legal(policy: np.ndarray, states: np.ndarray, spec: GameSpec, name: str) -> None:
    """``policy[s]`` is legal in every state ``s`` of ``states`` (visited states, whose
    masks are known: the chain's depend on the state alone)."""
    env, legal = spec.new_env(), np.zeros((spec.n_agents, spec.width), dtype=np.bool_)
    for s in np.flatnonzero(states):
        env[0][0] = s  # the chain's state is its only number
        spec.kernels.legal(env, legal)
        for i, action in enumerate(policy[s]):
            assert legal[i, action], f"{name}: greedy action {action} of agent {i} in state {s}"


def _check_two_team_play(config: Any, episodes: int) -> None:
    """Either side of the duel, against itself: learns, evaluates, repeats by seed."""
    results = []
    for _ in range(2):
        rngs = np.random.default_rng([5, 6]).spawn(3)
        match = Match(DUEL, (config, config), rngs[0], rngs[1:], episodes)
        match.learn()
        assert match.episodes == episodes and match.turns >= episodes
        result = match.evaluate(50, np.random.default_rng(9))
        assert sum(result.wins) + result.ties == 50, f"{config.name}: {result}"
        results.append(result)
    assert results[0] == results[1], f"{config.name}: the same seeds played two matches"


# -------------------------------------------------------------------------- deep


def stepped(model) -> bool:
    """Whether a deep model has taken a gradient step: its fused step's count (the fused
    step keeps its own Adam), else PyTorch's optimiser state."""
    fused = getattr(model, "fused", None)
    return fused.steps > 0 if fused is not None else bool(model.optimizer.state)


def check_deep_learner(config: DeepConfig, episodes: int = 300) -> None:
    """A stacked seed equals itself alone; legal greedy actions; both sides of a
    two-team game (small buffers, so that the check takes gradient steps)."""
    from cmarlcd.training.deep import DeepBatch

    small = replace(config, buffer_size=500, batch_size=32, train_every=8, target_every=64)
    final: dict[tuple[int, int], np.ndarray] = {}

    def keep(batch: int):
        return lambda k, budget, policy: final.__setitem__((batch, k), policy.table.copy())

    def seeds(*keys: int) -> list[np.random.SeedSequence]:
        return [np.random.SeedSequence(k) for k in keys]  # fresh: spawning changes them

    together = DeepBatch(CHAIN, small, seeds(0, 1), episodes)
    together.train([], keep(0))
    assert stepped(together.model), f"{config.name}: no gradient step was taken"
    alone = DeepBatch(CHAIN, small, seeds(1), episodes)
    alone.train([], keep(1))
    assert np.array_equal(final[0, 1], final[1, 0]), f"{config.name}: batched != alone"
    _assert_legal(final[0, 0], together.seen[0], CHAIN, config.name)
    _check_two_team_play(small, episodes)
