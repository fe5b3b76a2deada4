"""Every size a user can give is checked against a documented cap before anything is
planned: absurd sizes end in one line and exit 2, not in a sweep that lists 10^11 runs."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from cmarlcd import limits
from cmarlcd.cli import app
from cmarlcd.errors import ConfigError
from cmarlcd.experiments import compare, repeated, sensor_network, tournament
from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.tabular.coordination import StochasticConfig
from cmarlcd.runs import RunSpec

HUGE = "99999999999"

SIZES = [
    (["repeated", "--runs", HUGE], "--runs"),
    (["repeated", "--max-games", HUGE], "--max-games"),
    (["repeated", "--workers", HUGE], "--workers"),
    (["repeated", "--seed", "99999999999999999999999"], "--seed"),
    (["dsn", "--algorithms", "cmarl-cd", "--runs", "100000000000"], "--runs"),
    (["dsn", "--episodes", f"100k,{HUGE}"], "--episodes"),
    (["dsn", "--eval-episodes", HUGE], "--eval-episodes"),
    (["dsn", "--seed-batch", HUGE], "--seed-batch"),
    (["dsn", "--seed", "-1"], "--seed"),
    (["tournament", "--algorithms", "cmarl-cd", "--rounds", HUGE], "--rounds"),
    (["tournament", "--learn-episodes", HUGE + "k"], "--learn-episodes"),
    (["tournament", "--eval-episodes", HUGE], "--eval-episodes"),
    (["tournament", "--seed-batch", HUGE], "--seed-batch"),
    (["compare", "--runs", HUGE, "--games", "climbing", "--learners", "cmarl-cd"], "--runs"),
    (["compare", "--seed", str(2**63)], "--seed"),
    (["reproduce", "--workers", HUGE], "--workers"),
    (["reproduce", "--seed", str(2**63)], "--seed"),
]


@pytest.fixture
def nothing_is_planned(monkeypatch):
    """Listing a single run fails the test: sizes must be refused before any plan."""

    def planned(*args, **kwargs):
        raise AssertionError("a run was planned before the sizes were checked")

    monkeypatch.setattr(RunSpec, "make", planned)


@pytest.mark.parametrize(("args", "option"), SIZES, ids=[" ".join(a[:3]) for a, _ in SIZES])
def test_every_size_option_is_capped_before_anything_is_planned(
    tmp_path, nothing_is_planned, args, option
) -> None:
    store, figures = tmp_path / "s.sqlite", tmp_path / "figures"
    where = ["--store", str(store), "--figures", str(figures)]
    result = CliRunner().invoke(app, [*args, *where])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {option}:"), result.stderr
    assert not store.exists() and not figures.exists()


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["play", "--payoffs", "nowhere.npy", "--runs", HUGE], "--runs"),
        (["play", "--payoffs", "nowhere.npy", "--max-games", HUGE], "--max-games"),
        (["theory", "--starts", HUGE], "--starts"),
    ],
)
def test_commands_that_store_nothing_cap_their_sizes_too(args, option) -> None:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and result.stderr.startswith(f"error: {option}:"), result.stderr


def test_the_caps_count_runs_without_listing_them(nothing_is_planned) -> None:
    sweep = repeated.RepeatedSweep(1, (2, 3), (2, 3, 4), runs=5)
    assert sweep.run_count() == 2 * 3 * 5
    dsn = sensor_network.DsnSweep(
        learners=(StochasticConfig(), DeepConfig()), episodes=(10, 20, 30), runs=4
    )
    assert dsn.run_count() == 4 + 3 * 4  # the deep learner: one run per budget L
    known = tournament.battlefield_learners()
    contest = tournament.Tournament(tuple(known[n] for n in tournament.TABULAR), rounds=3)
    assert contest.run_count() == 3 * 3  # 2 learners: 2 pairings and 1 mirror match
    assert (
        compare.Comparison(
            (compare.registry.REPEATED_LEARNERS["cmarl-cd"],), ("climbing", "penalty-10"), runs=7
        ).run_count()
        == 2 * 7
    )


def test_a_sweep_of_exactly_the_cap_is_accepted_and_one_more_is_not() -> None:
    cells = 10  # 2 agent counts x 5 action counts
    runs = limits.MAX_RUNS // cells
    assert repeated.RepeatedSweep(1, (2, 3), (2, 3, 4, 5, 6), runs=runs).run_count() == (
        limits.MAX_RUNS
    )
    with pytest.raises(ConfigError, match="more than the 200,000 one sweep may hold"):
        repeated.RepeatedSweep(1, (2, 3), (2, 3, 4, 5, 6), runs=runs + 1)
