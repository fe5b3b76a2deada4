"""The learner comparison (beyond the paper): its runs, their seeds and its summary."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cmarlcd import registry
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import compare, settings_of
from cmarlcd.experiments.compare import (
    GAMES,
    CompareRun,
    Comparison,
    budget,
    run_compare,
    summarize,
)
from cmarlcd.games.matrix import climbing_game
from cmarlcd.learners.tabular.coordination import CMARLCD, RepeatedConfig
from cmarlcd.learners.tabular.q_learning import IQLConfig
from cmarlcd.registry import REPEATED_LEARNERS
from cmarlcd.runs import RunSpec
from cmarlcd.sweeps.store import RunRecord
from cmarlcd.training.repeated import fit


@pytest.mark.slow
def test_cmarlcd_through_the_comparison_plays_as_algorithm_1() -> None:
    """The watching loop consumes the learner's stream as fit does (deterministic games
    draw nothing): same games, same greedy joint action."""
    cell = CompareRun("climbing", RepeatedConfig(), 10_000_000)
    metrics = run_compare(cell, np.random.SeedSequence(5))
    _, _, learner_seed = np.random.SeedSequence(5).spawn(3)
    game = climbing_game()
    result = fit(CMARLCD(game.action_counts, RepeatedConfig(), seed=learner_seed), game)
    assert metrics["games"] == result.games and metrics["converged"] == result.converged
    assert metrics["optimal"] == result.success


def test_a_run_is_determined_by_its_seed() -> None:
    cell = CompareRun("climbing-fs", registry.repeated_learner("hysteretic"), 3_000)
    first = run_compare(cell, np.random.SeedSequence(1))
    assert first == run_compare(cell, np.random.SeedSequence(1))


def test_every_learner_meets_the_same_random_games(monkeypatch: pytest.MonkeyPatch) -> None:
    """Common random numbers: at one (size, run) CMARL-CD and IQL play the same random game
    (the same payoff table), and the runs of one size play different games."""
    family = GAMES["case1"]
    played: list[bytes] = []

    def make(size: tuple[int, int], rng: np.random.Generator) -> object:
        game = family.make(size, rng)
        played.append(game.payoffs.tobytes())
        return game

    monkeypatch.setitem(compare.GAMES, "case1", dataclasses.replace(family, make=make))
    sweep = Comparison((RepeatedConfig(), IQLConfig()), ("case1",), runs=3)
    smallest = min(family.sizes, key=lambda size: size[1] ** size[0])
    games: dict[int, set[bytes]] = {}
    for spec in sweep.specs():
        cell = settings_of(spec)
        if cell.size == smallest:
            run_compare(cell, spec.seed_sequence())
            games.setdefault(spec.key.run_index, set()).add(played[-1])
    assert len(games) == 3 and all(len(tables) == 1 for tables in games.values())
    assert len(set.union(*games.values())) == 3


def test_the_budget_grows_with_the_joint_actions() -> None:
    assert budget(9) == compare.MIN_GAMES
    assert budget(5**7) == compare.GAMES_PER_JOINT_ACTION * 5**7


def test_jal_is_left_out_of_games_too_large_for_it() -> None:
    sweep = Comparison(tuple(REPEATED_LEARNERS.values()), ("climbing", "case1"), runs=1)
    jal_sizes = [
        (s.config["agents"], s.config["actions"])
        for s in sweep.specs()
        if s.key.algorithm == "jal" and s.config["game"] == "case1"
    ]
    assert jal_sizes and all(m**n <= 1_024 for n, m in jal_sizes)
    assert ("jal", "case1") in sweep.skipped() and ("jal", "climbing") not in sweep.skipped()


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"games": ("chess",)}, "games"),
        ({"games": ()}, "games"),
        ({"runs": 0}, "runs"),
        ({"seed": -1}, "seed"),
        ({"learners": ()}, "learners"),
    ],
)
def test_bad_comparisons_are_rejected(kwargs, parameter) -> None:
    settings = {"learners": (IQLConfig(),), "games": ("climbing",), **kwargs}
    with pytest.raises(ConfigError) as err:
        Comparison(**settings)
    assert err.value.parameter == parameter


def test_summary_counts_runs_and_optimal_rates_per_learner_and_game() -> None:
    def record(learner: str, game: str, index: int, optimal: bool, settled: int, **size):
        where = (size["agents"], size["actions"]) if size else None
        cell = compare.CompareRun(game, registry.repeated_learner(learner), 10, where)
        spec = RunSpec.make(compare.EXPERIMENT, learner, cell, 0, index)
        return RunRecord(spec.key, {"optimal": optimal, "settled": settled}, 0.0, "test")

    records = [
        record("iql", "climbing", 0, True, 10),
        record("iql", "climbing", 1, False, 30),
        record("iql", "climbing", 2, True, 20),
        record("fmq", "case1", 0, True, 5, agents=2, actions=2),
        record("fmq", "case1", 1, False, 7, agents=3, actions=2),
    ]
    cells = {(c.learner, c.game): c for c in summarize(records)}
    assert cells[("iql", "climbing")].runs == 3
    assert cells[("iql", "climbing")].optimal_rate == pytest.approx(2 / 3)
    assert cells[("iql", "climbing")].median_games == 20
    fmq = cells[("fmq", "case1")]
    assert fmq.sizes == {
        "n=2,m=2": {"runs": 1, "optimal_rate": 1.0},
        "n=3,m=2": {"runs": 1, "optimal_rate": 0.0},
    }
    assert list(GAMES).index("climbing") < list(GAMES).index("case1")


def test_two_settings_of_one_learner_are_two_rows_named_by_their_settings() -> None:
    """Runs 0-1 of CMARL-CD at its comparison settings and at delta=0.2 on one game:
    two cells of two runs, the second named with its setting (they used to merge)."""

    def record(learner, index: int, optimal: bool) -> RunRecord:
        cell = compare.CompareRun("climbing", learner, 10)
        spec = RunSpec.make(compare.EXPERIMENT, learner.name, cell, 0, index)
        return RunRecord(spec.key, {"optimal": optimal, "settled": 5}, 0.0, "test")

    usual, other = RepeatedConfig(), dataclasses.replace(RepeatedConfig(), delta=0.2)
    records = [record(usual, i, True) for i in range(2)] + [record(other, i, False) for i in (0, 1)]
    cells = {c.label: (c.runs, c.optimal_rate) for c in summarize(records)}
    assert cells == {"CMARL-CD": (2, 1.0), "CMARL-CD (delta=0.2)": (2, 0.0)}


@pytest.mark.slow
def test_deep_cmarlcd_plays_the_comparison_with_its_one_step_settings() -> None:
    """Deep CMARL-CD is a learner of ``compare`` with its one-step preset; its runs store
    that preset and read back to it; it plays the small games only; on the climbing game
    its greedy joint action ends on the optimum, and "settled" is a game at which its
    greedy joint action was read (every train_every games)."""
    pytest.importorskip("torch")
    deep = registry.comparable_learner("deep-cmarl-cd")
    assert deep.train_every == 10 and deep.lr == 1e-2  # the one-step preset, not the DSN's
    sweep = Comparison((deep,), ("climbing", "case1"), runs=3)
    specs = sweep.specs()
    assert all(settings_of(s).learner == deep for s in specs)
    sizes = [(s.config["agents"], s.config["actions"]) for s in specs if "agents" in s.config]
    assert sizes and all(m**n <= 1_024 for n, m in sizes)
    assert ("deep-cmarl-cd", "case1") in sweep.skipped()
    for spec in specs[:3]:  # the climbing game
        metrics = run_compare(settings_of(spec), spec.seed_sequence())
        assert metrics["optimal"] and metrics["games"] == budget(9)
        assert metrics["settled"] % deep.train_every == 0 and metrics["settled"] <= budget(9)


def test_an_unknown_learner_lists_the_deep_ones_too() -> None:
    with pytest.raises(ConfigError, match="deep-cmarl-cd"):
        registry.comparable_learner("nope")


def test_settings_changed_for_compare_reach_the_dsn_too() -> None:
    """A learner changed from compare's default (``--set``) plays the DSN with the same
    change on top of its DSN settings; an unchanged one plays the DSN's own."""
    changed = dataclasses.replace(registry.comparable_learner("cmarl-cd"), delta=0.123)
    sweep = compare.Comparison(
        learners=(changed, registry.comparable_learner("iql")), games=("climbing", "dsn"),
        runs=1,
    )  # fmt: skip
    assert compare.changed_settings(changed) == {"delta": 0.123}
    dsn = {c.name: c for c in sweep.dsn_learners()}
    assert dsn["cmarl-cd"] == dataclasses.replace(registry.LEARNERS["cmarl-cd"], delta=0.123)
    assert dsn["iql"] == registry.LEARNERS["iql"]
