"""``cmarl-cd play --policy``: a kept policy watched step by step in its run's own
environment, its returns those of a plain PettingZoo loop of the loaded policy, and bad
input refused in one line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cmarlcd.games.sensor_network.env import SensorNetworkEnv
from cmarlcd.policies import load_policy
from tests.tiny_env import make_random_length

ROOT = Path(__file__).resolve().parents[2]


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cmarlcd", *args], capture_output=True, text=True, timeout=600,
        cwd=ROOT,
    )  # fmt: skip


def plain_returns(policy, env, episodes: int, seed: int, team=None) -> list[float]:
    """The policy in a plain PettingZoo loop: the first reset seeded, the next ones not."""
    team = team or (lambda rewards: sum(rewards.values()))
    returns = []
    for episode in range(episodes):
        observations, infos = env.reset(seed=seed if episode == 0 else None)
        total = 0.0
        while env.agents:
            masks = {a: infos[a].get("action_mask") for a in env.agents}
            given = None if any(m is None for m in masks.values()) else masks  # tiny: none
            actions = policy.act(observations, state=env.state(), masks=given)
            observations, rewards, _, _, infos = env.step(actions)
            total += team(rewards)
        returns.append(total)
    return returns


@pytest.fixture(scope="module")
def kept(tmp_path_factory) -> Path:
    """Policies of a train --env run (random lengths and pay) and of a DSN run."""
    where = tmp_path_factory.mktemp("kept")
    for command in (
        ("train", "--env", "tests.tiny_env:make_random_length", "--algorithms", "iql",
         "--episodes", "60", "--runs", "1", "--curve-points", "2"),
        ("dsn", "--algorithms", "cmarl-cd", "--episodes", "2k", "--runs", "1"),
        ("train", "--game", "simple_spread:N=3", "--algorithms", "qmix", "--inputs",
         "own-observations", "--steps", "600", "--runs", "1"),
        ("scaling", "--algorithms", "vdn", "--sizes", "3x4/3", "--episodes", "100", "--runs",
         "1"),
        ("field", "--tasks", "foraging:5x5-2p-1f", "--learners", "vdn", "--inputs",
         "own-observations", "--time-left", "--steps", "600", "--eval-interval", "300",
         "--eval-episodes", "2", "--seeds", "1"),
    ):  # fmt: skip
        done = cli(*command, "--workers", "1", "--no-progress", "--store",
                   str(where / "s.sqlite"), "--figures", str(where / "f"), "--save-policies",
                   str(where / "p"))  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
    return where / "p"


def test_watching_a_train_env_policy_plays_as_a_plain_loop(kept) -> None:
    path = next(kept.glob("train-iql-*.npz"))
    shown = cli("play", "--policy", str(path), "--episodes", "4", "--seed", "2", "--json")
    assert shown.returncode == 0, shown.stderr
    doc = json.loads(shown.stdout)
    expected = plain_returns(load_policy(path), make_random_length(), 4, 2)
    assert doc["returns"] == pytest.approx(expected, abs=1e-12)
    assert len(set(expected)) > 1  # random pay: the episodes differ, the check can fail
    assert sum(step["done"] for step in doc["steps"]) == 4


def test_watching_a_dsn_policy_shows_the_grid_step_by_step(kept) -> None:
    path = next(kept.glob("dsn-cmarl-cd-*.npz"))
    shown = cli("play", "--policy", str(path), "--episodes", "3", "--seed", "7", "--json")
    doc = json.loads(shown.stdout)
    policy = load_policy(path)
    team = lambda rewards: next(iter(rewards.values()))  # noqa: E731 - every sensor's is the team's
    expected = plain_returns(policy, SensorNetworkEnv(), 3, 7, team)
    assert doc["returns"] == pytest.approx(expected, abs=1e-9)
    text = cli("play", "--policy", str(path), "--seed", "7").stdout
    assert "captured:" in text and "step 1: sensor_0=" in text  # the grid, then the actions
    assert f"episode 0: return {expected[0]:g}" in text


@pytest.mark.parametrize(
    "pattern", ["dsn-cmarl-cd-*", "simple_spread-qmix-*", "scaling-vdn-*", "foraging-vdn-*"]
)
def test_watching_plays_the_episodes_evaluate_plays(kept, pattern) -> None:
    """The same seed, the same episodes: watched in the run's PettingZoo environment
    (reset with the seed, then its stream), played by evaluate in the compiled loop or
    the environment's copies (a table, QMIX's own-observation networks, VDN reading the
    scaled DSN's features, VDN reading LBF's observations and the time left); two paths,
    one return."""
    path = str(next(kept.glob(pattern)))
    watched = json.loads(cli("play", "--policy", path, "--episodes", "5", "--seed", "3",
                             "--json").stdout)  # fmt: skip
    played = json.loads(cli("evaluate", "--policy", path, "--episodes", "5", "--seed", "3",
                            "--json").stdout)  # fmt: skip
    assert np.mean(watched["returns"]) == pytest.approx(played["mean_return"], abs=1e-9)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((), "--payoffs: give --payoffs or --policy, one"),
        (("--policy", "nowhere.npz"), "--policy: nowhere.npz: no such file"),
        (("--policy", "POLICY", "--episodes", "0"), "--episodes: must be >= 1 (got 0)"),
        (("--policy", "POLICY", "--delay", "-1"), "--delay: must be in [0, 10] seconds"),
        (("--policy", "POLICY", "--payoffs", "x.npy"), "give --payoffs or --policy, one"),
    ],
)
def test_bad_play_input_is_one_line_and_exit_2(kept, args, message) -> None:
    path = str(next(kept.glob("dsn-*.npz")))
    done = cli("play", *(path if a == "POLICY" else a for a in args))
    assert done.returncode == 2
    assert message in done.stderr and len(done.stderr.strip().splitlines()) == 1
