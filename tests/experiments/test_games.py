"""``cmarl-cd train --game NAME:TASK`` (experiments/games.py, reports/game_training.py) on
Level-Based Foraging and simple_spread: end to end as a user runs it, bad input refused in
one line, the random floor."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.experiments import games
from cmarlcd.games.foraging import Foraging, ForagingEnv
from cmarlcd.registry import LEARNERS

ROOT = Path(__file__).resolve().parents[2]


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cmarlcd", "train", *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=cwd,
    )


def test_train_on_a_foraging_task_end_to_end_and_resumed(tmp_path) -> None:
    args = [
        "--game", "foraging:5x5-2p-1f,penalty=0.1", "--algorithms", "cmarl-cd,vdn",
        "--episodes", "300", "--runs", "2", "--eval-episodes", "50", "--curve-points", "3",
        "--seed-batch", "2", "--workers", "2", "--no-progress", "--json",
        "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
    ]  # fmt: skip
    done = cli(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    doc = json.loads(done.stdout)
    assert doc["runs_computed"] == 4
    section = doc
    assert section["experiment"] == "foraging"
    assert section["game"] == "foraging:5x5-2p-1f,penalty=0.1"
    rows = {row["label"]: row for row in section["rows"]}
    assert set(rows) == {"random policy", "CMARL-CD", "VDN"}
    assert rows["CMARL-CD"]["runs"] == 2
    floor = rows["random policy"]["mean_return"]
    assert rows["VDN"]["above_random"] == pytest.approx(rows["VDN"]["mean_return"] - floor)
    assert 0 <= rows["random policy"]["success_rate"] <= 1
    assert Path(section["figures"]["curves"]).exists()
    again = cli(*args, cwd=tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    redone = json.loads(again.stdout)
    assert redone["runs_computed"] == 0 and redone["runs_reused"] == 4
    assert redone["rows"] == section["rows"]
    report = subprocess.run(
        [sys.executable, "-m", "cmarlcd", "report", "--store", str(tmp_path / "s.sqlite"),
         "--figures", str(tmp_path / "r")],
        capture_output=True, text=True, timeout=300, cwd=tmp_path,
    )  # fmt: skip
    assert report.returncode == 0, report.stderr[-3000:]
    assert "Learning on foraging 5x5-2p-1f,penalty=0.1" in report.stdout
    assert "random policy" in report.stdout and "CMARL-CD" in report.stdout


def test_a_budget_of_steps_end_to_end(tmp_path) -> None:
    args = [
        "--game", "foraging:5x5-2p-1f", "--algorithms", "cmarl-cd,vdn", "--steps", "3k",
        "--runs", "2", "--eval-episodes", "20", "--curve-points", "3", "--workers", "1",
        "--no-progress", "--json", "--store", str(tmp_path / "s.sqlite"),
        "--figures", str(tmp_path / "f"),
    ]  # fmt: skip
    done = cli(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    doc = json.loads(done.stdout)
    assert (doc["budget"], doc["unit"]) == (3000, "steps")
    assert "3,000 environment steps" in doc["settings"]
    vdn = doc["curves"]["VDN"]
    assert [point[0] for point in vdn[0]] == [1000, 2000, 3000]
    # the field's figures of each learner's curve: the best point of the mean over runs,
    # and the mean over every point
    means = [sum(run[k][1] for run in vdn) / len(vdn) for k in range(3)]
    field = doc["field"]["VDN"]
    assert field["max_return"] == pytest.approx(max(means))
    assert field["max_return_at"] == [1000, 2000, 3000][means.index(max(means))]
    assert field["max_return_low"] <= field["max_return"] <= field["max_return_high"]
    assert field["average_return"] == pytest.approx(sum(means) / 3)
    assert (field["seeds"], field["points"]) == (2, 3)
    assert set(doc["field"]) == {"CMARL-CD", "VDN"}  # not the random policy


def test_train_on_simple_spread_end_to_end(tmp_path) -> None:
    args = [
        "--game", "simple_spread:N=2,local_ratio=0", "--algorithms", "vdn", "--steps", "2k",
        "--runs", "2", "--eval-episodes", "10", "--curve-points", "2", "--seed-batch", "2",
        "--workers", "1", "--no-progress", "--json", "--store", str(tmp_path / "s.sqlite"),
        "--figures", str(tmp_path / "f"),
    ]  # fmt: skip
    done = cli(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    doc = json.loads(done.stdout)
    assert doc["experiment"] == "simple_spread"
    assert doc["game"] == "simple_spread:N=2,local_ratio=0,max_cycles=25"
    rows = {row["label"]: row for row in doc["rows"]}
    assert set(rows) == {"random policy", "VDN"} and rows["VDN"]["runs"] == 2
    assert rows["random policy"]["mean_steps"] == 25.0  # never terminates: the cap
    assert Path(doc["figures"]["curves"]).exists()


def test_vdn_and_qmix_on_their_own_observations_end_to_end(tmp_path) -> None:
    args = [
        "--game", "simple_spread:N=2,reward=mean", "--inputs", "own-observations",
        "--algorithms", "vdn,qmix", "--episodes", "60", "--runs", "1", "--eval-episodes", "5",
        "--curve-points", "2", "--workers", "1", "--no-progress", "--json",
        "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
    ]  # fmt: skip
    done = cli(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    doc = json.loads(done.stdout)
    assert doc["inputs"] == "own-observations" and "each agent its own" in doc["settings"]
    assert "the mean of the agents'" in doc["settings"]
    assert {row["label"] for row in doc["rows"]} == {"random policy", "VDN", "QMIX"}


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--game", "chess:8x8"], "unknown game 'chess'"),
        (["--game", "simple_spread:N=0"], "N"),
        (["--game", "simple_spread:speed=2"], "takes N, local_ratio"),
        (["--game", "simple_spread", "--algorithms", "la-oca"], "no state index"),
        (["--game", "foraging:9x9-2p"], "not a foraging task"),
        (["--game", "foraging:8x8-2p-2f,speed=2"], "no rule 'speed'"),
        (["--game", "foraging:"], "name the task"),
        (["--game", "foraging:8x8-2p-2f", "--env", "tests.tiny_env:make"], "one of --env"),
        ([], "one of --env"),
        (["--game", "foraging:8x8-2p-2f", "--reward", "mean"], "--env only"),
        (
            [
                "--game",
                "foraging:5x5-2p-1f",
                "--algorithms",
                "cmarl-cd,vdn",
                "--inputs",
                "own-observations",
            ],
            "deep-cmarl-cd only (not cmarl-cd)",
        ),
        (["--game", "simple_spread", "--inputs", "pixels"], "inputs"),
        (["--game", "foraging:8x8-2p-2f", "--algorithms", "cmarl-cd"], "need a table"),
        (["--game", "foraging:8x8-2p-2f", "--seed-batch", "0"], "seed"),
        (["--game", "foraging:8x8-2p-2f", "--steps", "0"], "--steps"),
        (["--env", "tests.tiny_env:make", "--steps", "0"], "--steps"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, says) -> None:
    done = cli(*args, "--store", str(tmp_path / "s.sqlite"), cwd=ROOT)
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert says in line
    assert not (tmp_path / "s.sqlite").exists()


def test_tabular_learners_play_only_tasks_whose_table_fits() -> None:
    fits = games.FORAGING.tabular_fits
    assert fits(Foraging(5, 2, 1)) and fits(Foraging(8, 2, 1)) and not fits(Foraging(8, 2, 2))
    with pytest.raises(ConfigError, match="need a table"):
        games.GameSweep(
            learners=(LEARNERS["cmarl-cd"],),
            options=games.FORAGING.options(Foraging.from_name("8x8-2p-2f-coop")),
        )


def test_the_random_floor_is_the_uniform_policy_s_return() -> None:
    """The compiled uniform policy against one played through the ParallelEnv, on a task
    where it often collects the food: the same mean within 4 standard errors."""
    rules = Foraging(5, 2, 1)
    ours = games.uniform_floor(rules, 20_000, seed=0).returns
    env, rng, theirs = ForagingEnv(rules), np.random.default_rng(1), []
    env.reset(seed=1)
    for _ in range(1500):
        total, _ = 0.0, env.reset()
        while env.agents:
            _, rewards, _, _, _ = env.step({a: int(rng.integers(6)) for a in env.agents})
            total += rewards["agent_0"]
        theirs.append(total)
    error = np.sqrt(ours.var() / ours.size + np.var(theirs) / len(theirs))
    assert abs(ours.mean() - np.mean(theirs)) < 4 * error
    assert 0.2 < ours.mean() < 0.9  # a floor that is not trivially 0 or 1
