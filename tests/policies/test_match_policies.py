"""A tournament match keeps one policy a team: each replays the match's evaluation (the
stored wins and ties), plays with its partner in ``play``, and needs it beside it."""

from __future__ import annotations

import json
import shutil

import pytest

from tests.policies.test_kept_policies import cli


@pytest.fixture(scope="module")
def tournament(tmp_path_factory):
    """A small tournament of a tabular learner (LA-OCA, whose unseen states are played
    by uniform draws) and a deep one (VDN), its policies kept."""
    pytest.importorskip("torch")
    root = tmp_path_factory.mktemp("tournament")
    store, kept = root / "s.sqlite", root / "policies"
    done = cli(
        "tournament", "--algorithms", "la-oca,vdn", "--rounds", "2", "--learn-episodes", "150",
        "--eval-episodes", "60", "--unseen", "random", "--workers", "1", "--no-progress",
        "--store", str(store), "--figures", str(root / "f"), "--save-policies", str(kept),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return store, kept


def test_each_team_keeps_its_policy_and_replays_the_stored_wins(tournament) -> None:
    store, kept = tournament
    files = sorted(kept.iterdir())
    assert len(files) == 12  # 3 pairings x 2 rounds x 2 teams
    assert {f.suffix for f in files} == {".npz", ".safetensors"}  # LA-OCA's tables, VDN's nets
    outcomes = set()
    for path in files:
        doc = json.loads(cli("evaluate", "--policy", str(path), "--store", str(store),
                             "--json").stdout)  # fmt: skip
        assert doc["stored"] == {"wins": doc["wins"], "ties": doc["ties"]}, path.name
        assert sum(doc["wins"]) + doc["ties"] == doc["episodes"] == 60
        outcomes.add((tuple(doc["wins"]), doc["ties"]))
    assert len(outcomes) == 6  # both teams' files of a match give its one outcome
    other = json.loads(cli("evaluate", "--policy", str(files[0]), "--episodes", "60",
                           "--seed", "7", "--json").stdout)  # fmt: skip
    assert (tuple(other["wins"]), other["ties"]) not in outcomes  # other episodes


def test_a_match_is_watched_with_both_teams_playing(tournament) -> None:
    _, kept = tournament
    path = next(kept.glob("*la-oca vs vdn*team1.safetensors"))
    done = cli("play", "--policy", str(path), "--episodes", "2", "--delay", "0", "--json")
    assert done.returncode == 0, done.stderr[-2000:]
    doc = json.loads(done.stdout)
    steps = [f for f in doc["steps"] if f["step"] > 0]
    assert steps and all(len(f["actions"]) == 12 for f in steps)  # six agents a team
    assert {f["episode"] for f in steps} == {0, 1} and len(doc["returns"]) == 2
    # the reward is team 1's: a won episode returns at least 22 (its rule)
    assert all(r == sum(f["reward"] for f in steps if f["episode"] == e)
               for e, r in enumerate(doc["returns"]))  # fmt: skip


def test_a_match_policy_without_its_partner_is_one_line_and_exit_2(tournament, tmp_path) -> None:
    _, kept = tournament
    path = next(kept.glob("*team0*"))
    shutil.copy(path, tmp_path / path.name)
    for command in ("evaluate", "play"):
        done = cli(command, "--policy", str(tmp_path / path.name))
        assert done.returncode == 2
        assert "its team1 policy" in done.stderr and "is not beside it" in done.stderr
        assert len(done.stderr.strip().splitlines()) == 1
