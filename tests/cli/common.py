"""What the command line's end-to-end tests share: a runner that invokes the app in
process, the bound that tells a hang from a refusal, the check of a clean refusal, and
tiny runs of the commands they read."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from cmarlcd.cli import app

runner = CliRunner()

#: Seconds that tell a hang from a refusal: a refusal takes milliseconds, what it guards
#: against minutes; the bound is loose so that a loaded machine never fails the test.
HANG = 20


def invoke(*args: str):
    return runner.invoke(app, list(args))


def assert_rejected_cleanly(result, option: str, store, figures) -> None:
    """Exit 2, one line naming the option, nothing written."""
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {option}:"), result.stderr
    assert not store.exists() and not figures.exists()


def tiny_reproduction(paths, monkeypatch):
    """``reproduce`` of a tiny preset into ``paths``; returns its JSON document."""
    from cmarlcd.cli import reproduce as cli

    monkeypatch.setitem(cli.PRESETS, "quick", cli.PRESETS["smoke"])  # the default preset
    result = invoke("reproduce", "--workers", "1", "--json", *paths[2])
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def without_torch(monkeypatch) -> None:
    """Make the CLI see an install without the [deep] extra."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "torch" else real(name, *a)
    )


def tiny_paper_preset(monkeypatch) -> None:
    from cmarlcd.cli import reproduce as cli

    tiny = cli.Preset(
        1,
        1,
        dsn_eval_episodes=20,
        dsn_episodes=(30,),
        deep=True,
        tournament_rounds=1,
        tournament_episodes=20,
        compare_runs=1,
        compare_games=("climbing", "dsn"),
        compare_dsn_episodes=100,
    )
    monkeypatch.setitem(cli.PRESETS, "paper", tiny)


def small_repeated(where: list[str], runs: str = "2") -> object:
    args = ("--agents", "2-3", "--actions", "2", "--runs", runs, "--no-progress")
    return invoke("repeated", *args, *where)


SECTIONS = ("Table 1", "Table 2", "Tables 3-7", "Figs. 6-7", "Theorem 1", "Comparison")
