"""Kept policies: a table's and a network's written, read back and acting as the learner
did (every state of a table, 10^4 sampled inputs of a network), a kept policy replaying
its run's last evaluation to the stored figure, a loaded policy in a plain PettingZoo
loop, and bad files refused in one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cmarlcd import ConfigError, registry
from cmarlcd.policies import load_policy, write_policy
from cmarlcd.policies.learned import policy_of
from cmarlcd.training.episodes import play_episodes
from tests.tiny_env import TinyEnv

ROOT = Path(__file__).resolve().parents[2]
IDENTITY = {"experiment": "train", "algorithm": "x", "config_json": "{}", "stream_json": "",
            "root_seed": 0, "run_index": 0}  # fmt: skip


def round_trip(learner, tmp_path: Path, **meta):
    policy = policy_of(learner, {"inputs": "state", "agents": ["a", "b"], **meta})
    return load_policy(write_policy(tmp_path, policy, IDENTITY, "test"))


def test_a_table_acts_as_its_learner_on_every_state(tmp_path) -> None:
    from cmarlcd.learners.tabular.protocol import TabularLearner

    learner = TabularLearner([2, 3], registry.require_learner("distributed-q"), seed=3)
    states = [("room", k) for k in range(6)]
    rng = np.random.default_rng(0)
    for _ in range(300):  # visits with random rewards: the greedy actions differ by state
        for state in states:
            learner.act(state)
            learner.observe(state, (int(rng.integers(2)), int(rng.integers(3))), rng.random())
        learner.end_episode()
    loaded = round_trip(learner, tmp_path)
    assert loaded.keys == states  # tuples come back as tuples
    joints = {learner.greedy(state) for state in states}
    assert len(joints) > 1  # not one action everywhere: the check can fail
    for state in [*states, ("room", 99)]:  # a state never met: a fresh state's greedy
        assert loaded.greedy(state) == learner.greedy(state)


def test_a_table_of_integer_states_keeps_the_states_it_met(tmp_path) -> None:
    from cmarlcd.learners.tabular.protocol import TabularLearner

    learner = TabularLearner([3, 3], registry.require_learner("iql"), n_states=10, seed=1)
    rng = np.random.default_rng(1)
    for _ in range(200):
        for state in range(7):  # 7, 8 and 9 never met
            learner.act(state)
            learner.observe(state, tuple(int(a) for a in rng.integers(3, size=2)), rng.random())
        learner.end_episode()
    loaded = round_trip(learner, tmp_path)
    assert [loaded.greedy(s) for s in range(10)] == [learner.greedy(s) for s in range(10)]


@pytest.mark.parametrize(
    ("inputs", "learner_name"),
    [
        ("features", "vdn"),
        ("own", "qmix"),
        ("integers", "deep-iql"),
        ("features", "hysteretic-dqn"),
        ("own", "vdn-shared"),
    ],
)
def test_a_network_acts_as_its_learner_on_sampled_inputs(tmp_path, inputs, learner_name) -> None:
    pytest.importorskip("torch")
    from cmarlcd.learners.deep.agent import DeepAgent

    config = registry.require_learner(learner_name.removesuffix("-shared"))
    if learner_name.endswith("-shared"):
        config = replace(config, share=True)
    shape = {"features": {"state_dim": 6}, "own": {"state_dim": 6, "own_dim": 2},
             "integers": {"n_states": 40}}[inputs]  # fmt: skip
    learner = DeepAgent([3, 4], config, 10, seed=5, **shape)
    loaded = round_trip(learner, tmp_path)
    rng = np.random.default_rng(2)
    count = 10_000
    states = (
        list(rng.integers(40, size=count))
        if inputs == "integers"
        else list(rng.normal(size=(count, 6)).astype(np.float32))
    )
    masks = [[rng.random(3) < 0.7, rng.random(4) < 0.7] for _ in range(count)]
    masks = [[m if m.any() else ~m for m in pair] for pair in masks]
    for given in ([None] * count, masks):
        assert (loaded.greedy_many(states, given) == learner.greedy_many(states, given)).all()


def test_deep_cmarl_cd_acts_from_its_memory_where_it_keeps_the_state(tmp_path) -> None:
    pytest.importorskip("torch")
    from cmarlcd.learners.deep.degree_agent import DegreeAgent

    config = replace(registry.require_learner("deep-cmarl-cd"), act_from="memory")
    learner = DegreeAgent([2, 2], config, 60, state_dim=3, seed=4)
    play_episodes(TinyEnv(), learner, 60, seed=0)
    assert learner.stored > 0
    loaded = round_trip(learner, tmp_path)
    assert loaded.memory  # the kept states' degrees came along
    rng = np.random.default_rng(3)
    met = [np.eye(3, dtype=np.float32)[k] for k in range(3)]
    states = met + list(rng.normal(size=(10_000, 3)).astype(np.float32))
    masks = [None] * len(states)
    assert (loaded.greedy_many(states, masks) == learner.greedy_many(states, masks)).all()


def test_a_loaded_policy_in_a_plain_pettingzoo_loop(tmp_path) -> None:
    """CMARL-CD learns the tiny game's optimum (return 3); loaded, it plays it again with
    nothing of the project's loop: observations in, actions out."""
    from cmarlcd.learners.tabular.protocol import TabularLearner

    env = TinyEnv(state="integer")
    learner = TabularLearner([2, 2], registry.require_learner("cmarl-cd"), n_states=3, seed=0)
    play_episodes(env, learner, 300, seed=0)
    policy = round_trip(learner, tmp_path)
    observations, _ = env.reset(seed=1)
    total = 0.0
    while env.agents:
        actions = policy.act(observations, state=env.state())
        observations, rewards, _, _, _ = env.step(actions)
        total += sum(rewards.values())
    assert total == 3.0
    with pytest.raises(ConfigError, match="state"):
        policy.act(observations)  # it learned from the state: it needs it


def cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cmarlcd", *args], capture_output=True, text=True, timeout=600,
        cwd=cwd,
    )  # fmt: skip


def evaluated(*args: str) -> dict:
    """``cmarl-cd evaluate ARGS --json``'s document, run in this process: the loops below
    evaluate many policies, and each start of the command costs seconds; every test
    runs the command as a user does, a subprocess, at least once too."""
    from typer.testing import CliRunner

    from cmarlcd.cli import app

    done = CliRunner().invoke(app, ["evaluate", *args, "--json"])
    assert done.exit_code == 0, done.output
    return json.loads(done.stdout)


def test_evaluate_replays_the_runs_last_evaluation(tmp_path) -> None:
    """Kept with train --env --save-policies, each policy's evaluate gives its run's last
    curve point (random lengths and pay: other seeds give another return)."""
    pytest.importorskip("torch")
    store, kept = tmp_path / "s.sqlite", tmp_path / "policies"
    for learner, inputs in (("iql", "state"), ("vdn", "observations")):
        done = cli(
            "train", "--env", "tests.tiny_env:make_random_length", "--algorithms", learner,
            "--inputs", inputs, "--episodes", "60", "--runs", "2", "--eval-episodes", "7",
            "--curve-points", "2", "--envs", "3", "--workers", "1", "--no-progress", "--store",
            str(store), "--figures", str(tmp_path / "f"), "--save-policies", str(kept),
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
    files = sorted(kept.iterdir())
    assert [f.suffix for f in files] == [".npz", ".npz", ".safetensors", ".safetensors"]
    mask = os.umask(0)
    os.umask(mask)  # as any file the user makes (the library alone writes 0600)
    assert {f.stat().st_mode & 0o777 for f in files} == {0o666 & ~mask}
    stored = {}
    for k, path in enumerate(files):
        args = ("--policy", str(path), "--store", str(store))
        if k == 0:
            shown = cli("evaluate", *args, "--json")
            assert shown.returncode == 0, shown.stderr
            doc = json.loads(shown.stdout)
        else:
            doc = evaluated(*args)
        assert doc["mean_return"] == doc["stored_return"] and doc["episodes"] == 7
        stored[path] = doc["stored_return"]
    other = json.loads(cli("evaluate", "--policy", str(files[0]), "--seed", "9", "--json").stdout)
    assert other["mean_return"] != stored[files[0]]


def test_policies_kept_on_the_dsn_replay_their_last_curve_point(tmp_path) -> None:
    """The compiled DSN's CMARL-CD and LA-OCA tables, and VDN's and deep CMARL-CD's
    greedy tables (one-hot state inputs, seeds trained together): evaluate gives each
    run's stored last point (a random game: other seeds give another return)."""
    store, kept = tmp_path / "s.sqlite", tmp_path / "policies"
    done = cli(
        "dsn", "--algorithms", "cmarl-cd,la-oca,vdn,deep-cmarl-cd", "--episodes", "1k",
        "--runs", "2", "--eval-episodes", "300", "--workers", "1", "--no-progress",
        "--store", str(store), "--figures", str(tmp_path / "f"), "--save-policies", str(kept),
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    files = sorted(kept.glob("dsn-*.npz"))
    assert len(files) == 8
    returns = set()
    for path in files:
        doc = evaluated("--policy", str(path), "--store", str(store))
        assert doc["mean_return"] == doc["stored_return"]
        returns.add(doc["mean_return"])
    assert len(returns) == len(files)  # eight policies, eight figures: the check can fail
    other = json.loads(cli("evaluate", "--policy", str(files[0]), "--episodes", "300",
                           "--seed", "5", "--json").stdout)  # fmt: skip
    first = evaluated("--policy", str(files[0]))
    assert other["mean_return"] != first["mean_return"]


def test_networks_kept_on_a_compiled_game_replay_their_last_curve_point(tmp_path) -> None:
    """simple_spread's VDN and QMIX (one network shared by the agents), each agent
    reading its own observation, and LBF's
    deep CMARL-CD reading every observation and acting from its memory where it keeps
    the state: each seed's networks as its last evaluation played them, replayed to the
    stored return (simple_spread's is continuous: a single different action shows)."""
    store, kept = tmp_path / "s.sqlite", tmp_path / "policies"
    for game, learners, inputs, extra in (
        ("simple_spread:N=3", "vdn,qmix", "own-observations",
         ("--set", "qmix.share=true")),
        ("foraging:5x5-2p-1f", "deep-cmarl-cd", "observations",
         ("--set", "deep-cmarl-cd.act_from=memory")),
    ):  # fmt: skip
        done = cli(
            "train", "--game", game, "--algorithms", learners, "--steps",
            "1500", "--runs", "2", "--inputs", inputs, *extra, "--workers", "1",
            "--no-progress", "--store", str(store), "--figures", str(tmp_path / "f"),
            "--save-policies", str(kept),
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
    files = sorted(kept.glob("*.safetensors"))
    assert len(files) == 6
    for path in kept.glob("foraging-deep-cmarl-cd-*"):
        assert len(load_policy(path).arrays()["memory_keys"]) > 0
    for k, path in enumerate(files):
        args = ("--policy", str(path), "--store", str(store))
        doc = json.loads(cli("evaluate", *args, "--json").stdout) if k == 0 else evaluated(*args)
        assert doc["mean_return"] == doc["stored_return"]


def test_greedy_joint_actions_kept_on_repeated_games_give_the_stored_payoff(tmp_path) -> None:
    """compare's and repeated's runs keep their greedy joint action: on the fully
    stochastic climbing game its expected payoff, on random games (remade from each run's
    seeds: a wrong game gives another payoff) the payoff the run stored; deep
    CMARL-CD's too."""
    store, kept = tmp_path / "s.sqlite", tmp_path / "policies"
    for games, learners in (("climbing-fs,case1", "cmarl-cd,hysteretic"),
                            ("climbing-fs", "deep-cmarl-cd")):  # fmt: skip
        done = cli("compare", "--games", games, "--learners", learners, "--runs", "1",
                   "--workers", "1", "--no-progress", "--store", str(store), "--figures",
                   str(tmp_path / "f"), "--save-policies", str(kept))  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
    files = sorted(kept.glob("compare-*.npz"))
    assert any("deep-cmarl-cd" in f.name for f in files) and len(files) > 10
    payoffs = set()
    for k, path in enumerate(files[::3]):
        args = ("--policy", str(path), "--store", str(store))
        doc = json.loads(cli("evaluate", *args, "--json").stdout) if k == 0 else evaluated(*args)
        assert doc["mean_return"] == doc["stored_return"]
        payoffs.add(doc["mean_return"])
    assert len(payoffs) > 2  # random games, other payoffs: the check can fail
    done = cli("repeated", "--case", "2", "--agents", "3", "--actions", "4", "--runs", "3",
               "--workers", "1", "--no-progress", "--store", str(store), "--figures",
               str(tmp_path / "f"), "--save-policies", str(kept))  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    joints = set()
    for path in kept.glob("repeated-*.npz"):  # each an optimum (1) of its own random game
        doc = evaluated("--policy", str(path), "--store", str(store))
        assert doc["mean_return"] == doc["stored_return"] == 1.0 and doc["optimal"]
        joints.add(tuple(doc["greedy_joint_action"]))
    assert len(joints) == 3  # three games, three optima: a game remade wrong would miss


def test_save_policies_where_no_run_keeps_one_is_refused() -> None:
    from cmarlcd.cli.sweeps import check_keeps_policies
    from cmarlcd.experiments import theorem

    checks = theorem.specs(seed=0)
    with pytest.raises(ConfigError, match="the runs of theorem1 keep no policy"):
        check_keeps_policies(checks)


def test_bad_policy_files_are_one_line_and_exit_2(tmp_path) -> None:
    from cmarlcd.learners.tabular.protocol import TabularLearner

    learner = TabularLearner([2, 2], registry.require_learner("iql"), n_states=3, seed=0)
    good = round_trip(learner, tmp_path)
    path = next(tmp_path.glob("*.npz"))
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:200])
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, x=np.zeros(3))
    newer = tmp_path / "newer.npz"
    meta = {**good.metadata, "format": 99, "keys": None}
    np.savez(newer, **good.arrays(), __metadata__=np.array(json.dumps(meta)))
    (tmp_path / "notes.txt").write_text("hello")
    cases = {
        tmp_path / "missing.npz": "no such file",
        tmp_path / "notes.txt": "not a policy file",
        truncated: "not a readable policy file",
        foreign: "without cmarl-cd's metadata",
        newer: "a newer format",
    }
    for bad, says in cases.items():
        with pytest.raises(ConfigError, match=says):
            load_policy(bad)
        done = cli("evaluate", "--policy", str(bad), cwd=tmp_path)
        assert done.returncode == 2 and says in done.stderr, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1
