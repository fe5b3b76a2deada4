"""``cmarl-cd field``: tasks x learners x seeds at the field's protocol, as a user runs
it (a subprocess), killed with SIGKILL and resumed; its task list; bad input."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cmarlcd import ConfigError, registry
from cmarlcd.cli.field import env_episode_steps, evaluation_points, split_tasks, with_preset

pytest.importorskip("torch")

#: The repository's root: ``tests.tiny_env`` imports from there.
ROOT = Path(__file__).resolve().parents[1]
TINY = [
    "--learners", "deep-iql,vdn", "--seeds", "2", "--steps", "3k", "--eval-interval", "1k",
    "--eval-episodes", "5", "--workers", "1", "--no-progress",
]  # fmt: skip


def field(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cmarlcd", "field", *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=cwd,
    )


def test_a_rule_after_a_task_belongs_to_it() -> None:
    assert split_tasks("foraging:5x5-2p-1f,penalty=0.1,simple_spread:N=2,local_ratio=0") == [
        "foraging:5x5-2p-1f,penalty=0.1",
        "simple_spread:N=2,local_ratio=0",
    ]
    assert split_tasks("simple_spread, foraging:8x8-2p-2f-coop,simple_spread") == [
        "simple_spread",
        "foraging:8x8-2p-2f-coop",
    ]
    with pytest.raises(ConfigError, match="a rule before any task"):
        split_tasks("penalty=0.1,foraging:5x5-2p-1f")
    with pytest.raises(ConfigError, match="at least one task"):
        split_tasks(" , ")


def test_an_evaluation_every_interval_and_one_at_the_end() -> None:
    assert evaluation_points(2_050_000, 50_000) == 41
    assert evaluation_points(3_000, 1_000) == 3
    assert evaluation_points(3_500, 1_000) == 4
    with pytest.raises(ConfigError, match="at most the budget"):
        evaluation_points(1_000, 2_000)


def test_two_tasks_end_to_end_with_the_fields_figures(tmp_path) -> None:
    done = field(
        "--tasks", "foraging:5x5-2p-1f,simple_spread:N=2", *TINY, "--json",
        "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
        cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    doc = json.loads(done.stdout)
    assert doc["runs_computed"] == 8  # 2 tasks x 2 learners x 2 seeds
    games = [task["game"] for task in doc["tasks"]]
    assert games == ["foraging:5x5-2p-1f", "simple_spread:N=2,local_ratio=0.5,max_cycles=25"]
    for task in doc["tasks"]:
        assert (task["budget"], task["unit"]) == (3000, "steps")
        curve = task["curves"]["VDN"]
        # EPyMARL's protocol: an evaluation before learning, then one every interval
        assert [point[0] for point in curve[0]] == [0, 1000, 2000, 3000]
        means = [sum(run[k][1] for run in curve) / len(curve) for k in range(4)]
        assert task["field"]["VDN"]["max_return"] == pytest.approx(max(means))
        assert task["field"]["Deep IQL"]["seeds"] == 2


def test_the_evaluation_at_start_changes_nothing_the_runs_learn(tmp_path) -> None:
    """Without it the curve starts at the first interval; with it, the same seeds give
    the same later points (the evaluation draws from streams of its own)."""
    curves = {}
    for flag in ("--no-eval-at-start", "--eval-at-start"):
        done = field(
            "--tasks", "simple_spread:N=2", *TINY, flag, "--json",
            "--store", str(tmp_path / f"{flag}.sqlite"), "--figures", str(tmp_path / "f"),
            cwd=tmp_path,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        (task,) = json.loads(done.stdout)["tasks"]
        curves[flag] = task["curves"]
    assert [point[0] for point in curves["--no-eval-at-start"]["VDN"][0]] == [1000, 2000, 3000]
    for learner, runs in curves["--eval-at-start"].items():
        assert [run[1:] for run in runs] == curves["--no-eval-at-start"][learner]


def test_the_time_left_is_read_and_its_runs_stored_apart(tmp_path) -> None:
    """``--time-left``: the learners read one more number per agent, the section says so,
    and the same command without it computes its own runs in the same store."""
    store = str(tmp_path / "s.sqlite")
    tiny = ["--learners", "deep-cmarl-cd,vdn", *TINY[2:], "--inputs", "own-observations"]
    set_shares = ["--set", "deep-cmarl-cd.design=shares-cold"]
    docs = {}
    for flag in ("--time-left", "--no-time-left"):
        done = field(
            "--tasks", "foraging:5x5-2p-1f", *tiny, *set_shares, flag, "--json",
            "--store", store, "--figures", str(tmp_path / "f"), cwd=tmp_path,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        docs[flag] = json.loads(done.stdout)
    for flag, doc in docs.items():
        assert doc["runs_computed"] == 4 and doc["runs_reused"] == 0, flag
        (task,) = doc["tasks"]
        assert task["time_left"] is (flag == "--time-left")
        assert ("and the time left" in json.dumps(task)) is (flag == "--time-left")
    with sqlite3.connect(store) as db:
        assert db.execute("select count(*) from runs").fetchone()[0] == 8


def test_the_epymarl_preset_sets_epymarls_numbers_per_task() -> None:
    vdn, iql, cmarl = (registry.require_learner(n) for n in ("vdn", "deep-iql", "deep-cmarl-cd"))
    assert with_preset((vdn, cmarl), "paper", 25) == (vdn, cmarl)
    # simple_spread's 25-step episodes: EPyMARL's batches of 32 episodes, a buffer of 5,000
    # episodes, a gradient step per episode and a target copy every 200 episodes
    epy_vdn, epy_iql, same = with_preset((vdn, iql, cmarl), "epymarl", 25)
    assert same is cmarl  # deep CMARL-CD keeps its own settings
    assert (epy_vdn.batch_size, epy_vdn.buffer_size) == (32 * 25, 5_000 * 25)
    assert (epy_vdn.train_every, epy_vdn.target_every) == (25, 200 * 25)
    assert (epy_vdn.lr, epy_vdn.hidden, epy_vdn.anneal_steps) == (5e-4, 64, 50_000)
    assert (epy_vdn.gamma, epy_vdn.eps_start, epy_vdn.eps_end) == (0.99, 1.0, 0.05)
    assert epy_vdn.double_q and epy_vdn.standardise_rewards and epy_vdn.grad_clip == 10.0
    assert (epy_iql.lr, epy_iql.hidden, epy_iql.anneal_steps) == (3e-4, 128, 200_000)
    assert epy_iql.mixer == "independent"


def test_the_epymarl_preset_end_to_end_named_in_the_rows(tmp_path) -> None:
    done = field(
        "--tasks", "simple_spread:N=2", "--learners", "vdn,deep-iql", "--preset", "epymarl",
        "--set", "vdn.lr=0.001", "--seeds", "2", "--steps", "2k", "--eval-interval", "1k",
        "--eval-episodes", "5", "--workers", "1", "--no-progress", "--json",
        "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
        cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    (task,) = json.loads(done.stdout)["tasks"]
    assert set(task["field"]) == {"VDN (EPyMARL, lr=0.001)", "Deep IQL (EPyMARL)"}


def test_an_env_task_beside_a_compiled_one_with_its_random_floor(tmp_path) -> None:
    done = field(
        "--tasks", "simple_spread:N=2", "--env", "tests.tiny_env:make", "--envs", "2", *TINY,
        "--json", "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
        cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    doc = json.loads(done.stdout)
    assert doc["runs_computed"] == 4 + 6  # the env task: 2 learners and the random policy
    compiled, tiny = doc["tasks"]
    assert compiled["game"] == "simple_spread:N=2,local_ratio=0.5,max_cycles=25"
    assert (tiny["env"], tiny["unit"]) == ("tests.tiny_env:make", "steps")
    assert set(tiny["curves"]) == {"random policy", "Deep IQL", "VDN"}
    for runs in tiny["curves"].values():  # evaluated before learning, then every interval
        assert [[point[0] for point in run] for run in runs] == [[0, 1000, 2000, 3000]] * 2
    vdn = tiny["curves"]["VDN"]
    averages = [sum(point[1] for point in run) / 4 for run in vdn]
    assert tiny["field"]["VDN"]["average_return"] == pytest.approx(sum(averages) / 2)
    assert tiny["field"]["VDN"]["points"] == 4
    # the same numbers from the store alone
    again = subprocess.run(
        [sys.executable, "-m", "cmarlcd", "report", "--store", str(tmp_path / "s.sqlite"),
         "--figures", str(tmp_path / "g"), "--format", "json"],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )  # fmt: skip
    assert again.returncode == 0, again.stderr[-3000:]
    (stored,) = [task for task in json.loads(again.stdout)["train"] if "env" in task]
    assert stored["field"] == tiny["field"] and stored["curves"] == tiny["curves"]


def test_the_epymarl_preset_on_an_env_task_reads_its_episode_length(tmp_path) -> None:
    assert env_episode_steps("tests.tiny_env:make_declaring", (), None) == 3
    assert env_episode_steps("tests.tiny_env:make", (), 7) == 7
    with pytest.raises(ConfigError, match="declares none"):
        env_episode_steps("tests.tiny_env:make", (), None)
    args = [
        "--learners", "vdn", "--preset", "epymarl", "--seeds", "1", "--steps", "60",
        "--eval-interval", "30", "--eval-episodes", "2", "--workers", "1", "--no-progress",
        "--json", "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
    ]  # fmt: skip
    done = field("--env", "tests.tiny_env:make", *args, cwd=ROOT)
    assert done.returncode == 2 and "--episode-steps" in done.stderr, done.stderr
    done = field("--env", "tests.tiny_env:make_declaring", *args, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    (task,) = json.loads(done.stdout)["tasks"]
    assert set(task["field"]) == {"VDN (EPyMARL)"}
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        (config,) = db.execute("select config from runs where algorithm = 'vdn'").fetchone()
    learner = json.loads(config)["learner"]  # EPyMARL's episodes, in 3-step episodes
    assert (learner["batch_size"], learner["target_every"]) == (32 * 3, 200 * 3)


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")
def test_killed_with_sigkill_and_resumed_to_the_same_store(tmp_path) -> None:
    store = tmp_path / "s.sqlite"
    args = [
        sys.executable, "-m", "cmarlcd", "field", "--tasks", "simple_spread:N=2",
        "--learners", "vdn", "--seeds", "4", "--seed-batch", "1", "--steps", "60k",
        "--eval-interval", "30k", "--eval-episodes", "5", "--workers", "1", "--no-progress",
        "--store", str(store), "--figures", str(tmp_path / "f"),
    ]  # fmt: skip
    process = subprocess.Popen(args, cwd=tmp_path, start_new_session=True)

    def stored() -> int:
        if not store.exists():
            return 0
        try:
            with sqlite3.connect(store) as db:
                return db.execute("select count(*) from runs").fetchone()[0]
        except sqlite3.Error:
            return 0

    deadline = time.monotonic() + 300
    while stored() < 1 and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    before = stored()
    assert 1 <= before < 4  # killed mid-sweep
    again = subprocess.run(
        [*args, "--json"], capture_output=True, text=True, timeout=600, cwd=tmp_path
    )
    assert again.returncode == 0, again.stderr[-3000:]
    doc = json.loads(again.stdout)
    assert doc["runs_reused"] == before and doc["runs_computed"] == 4 - before
    assert stored() == 4


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--tasks", "nowhere:1"], "--tasks: nowhere:1: unknown game 'nowhere'"),
        (["--tasks", "foraging:9x9"], "--tasks: foraging:9x9"),
        (["--tasks", "simple_spread", "--learners", "nope"], "--learners: unknown 'nope'"),
        (["--tasks", "simple_spread", "--learners", "cmarl-cd"], "need a table"),
        (["--tasks", "simple_spread", "--inputs", "pixels"], "--inputs"),
        (["--tasks", "simple_spread", "--eval-interval", "5M"], "at most the budget"),
        (["--tasks", "simple_spread", "--seeds", "0"], "--seeds"),
        (["--tasks", "simple_spread", "--preset", "pymarl"], "--preset: must be one of"),
        (["--tasks", "foraging:8x8-2p-2f-coop", "--learners", "iql"], "deep IQL is deep-iql"),
        ([], "give --tasks"),
        (["--tasks", "simple_spread", "--envs", "4"], "--envs: applies to --env only"),
        (["--env", "nowhere:make"], "--env: nowhere:make: cannot import"),
        (["--env", "tests.tiny_env:make", "--learners", "cmarl-cd"], "--learners: tests.tiny"),
        (["--env", "tests.tiny_env:make", "--steps", "2k", "--eval-interval", "10"], "--eval-i"),
        (["--env", "tests.tiny_env:make", "--env-kwargs", "[1]"], "--env-kwargs: expected"),
        (["--env", "tests.tiny_env:make", "--time-left"], "--time-left: applies to --tasks"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, says) -> None:
    done = field(*args, "--store", str(tmp_path / "s.sqlite"), cwd=ROOT)
    assert done.returncode == 2, done.stderr
    assert says in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not (tmp_path / "s.sqlite").exists()
