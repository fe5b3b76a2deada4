"""``cmarl-cd train``: learners on any PettingZoo ParallelEnv, end to end on tiny budgets."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from cmarlcd.experiments import environment as envs
from cmarlcd.experiments import settings_of
from cmarlcd.experiments.env_inputs import StateShape
from cmarlcd.sweeps.store import ResultStore
from tests.cli.common import assert_rejected_cleanly, invoke
from tests.tiny_env import TinyEnv

TINY = "tests.tiny_env:make"


def test_the_random_policy_earns_what_chance_gives() -> None:
    """Uniform over 2 actions each: both choose 1 with probability 1/4 at each of 3 steps."""
    from cmarlcd.training.episodes import play_episodes

    env = TinyEnv()
    policy = envs.RandomPolicy(np.array([2, 2]), np.random.SeedSequence(0))
    team = envs.REWARDS["sum"]
    stats = play_episodes(env, policy, 4_000, learn=False, seed=0, global_reward=team)
    assert stats.returns.mean() == pytest.approx(0.75, abs=0.05)
    assert set(stats.lengths) == {3}


def test_team_rewards() -> None:
    assert envs.REWARDS["sum"]({"a": 0.5, "b": 0.5}) == 1.0
    assert envs.REWARDS["mean"]({"a": 0.5, "b": 1.5}) == 1.0


def test_only_the_deep_learners_read_their_own_observations() -> None:
    pytest.importorskip("torch")
    from cmarlcd import ConfigError, registry

    shape = StateShape(None, 9, 3)
    seed = np.random.SeedSequence(0)
    counts = np.array([2, 2])
    assert envs.new_learner(registry.require_learner("qmix"), counts, shape, 10, seed)
    assert envs.new_learner(registry.require_learner("deep-cmarl-cd"), counts, shape, 10, seed)
    fused = replace(registry.require_learner("deep-cmarl-cd"), step="fused")
    assert envs.new_learner(fused, counts, shape, 10, seed).model.fused is not None
    with pytest.raises(ConfigError, match="own-observations is for vdn, qmix, deep-iql"):
        envs.check_reads_own_observations(registry.require_learner("cmarl-cd"), "own-observations")


def test_each_agent_reads_its_own_observation_end_to_end(paths) -> None:
    """``--inputs own-observations``: VDN and QMIX learn the tiny game's optimum from
    their own observations, and the report names the inputs."""
    pytest.importorskip("torch")
    _, _, where = paths
    result = invoke(
        "train", "--env", TINY, "--algorithms", "vdn,qmix", "--episodes", "300", "--runs", "1",
        "--eval-episodes", "4", "--curve-points", "1", "--inputs", "own-observations", "--json",
        *where, "--set", "vdn.batch_size=32,vdn.train_every=3,"
        "qmix.batch_size=32,qmix.train_every=3",
    )  # fmt: skip
    assert result.exit_code == 0, result.stderr
    rows = {r["algorithm"]: r for r in json.loads(result.stdout)["rows"]}
    assert rows["vdn"]["mean_return"] == 3.0 and rows["qmix"]["mean_return"] == 3.0
    assert "inputs: own-observations" in invoke("report", *where).stdout


def test_the_learners_end_to_end(paths) -> None:
    """Deep CMARL-CD, VDN and the random baseline on the tiny env: stored curves, the
    greedy deep CMARL-CD finds the optimum 3, the baseline earns about 3/4; a second call
    computes nothing; report has the section."""
    pytest.importorskip("torch")
    store, _, where = paths
    args = (
        "train", "--env", TINY, "--algorithms", "deep-cmarl-cd,vdn", "--episodes", "400",
        "--runs", "2", "--eval-episodes", "20", "--curve-points", "4", "--json", *where,
        "--set", "deep-cmarl-cd.batch_size=32,deep-cmarl-cd.train_every=3,"
        "vdn.batch_size=32,vdn.train_every=3",
    )  # fmt: skip
    result = invoke(*args)
    assert result.exit_code == 0, result.stderr
    doc = json.loads(result.stdout)
    assert doc["runs_computed"] == 6
    rows = {r["algorithm"]: r for r in doc["rows"]}
    assert set(rows) == {"random", "deep-cmarl-cd", "vdn"}
    assert rows["deep-cmarl-cd"]["mean_return"] == 3.0
    assert 0.2 <= rows["random"]["mean_return"] <= 1.5
    with ResultStore(store) as db:
        curves = [r.metrics["curve"] for r in db.records(envs.EXPERIMENT)]
    assert all([p[0] for p in c] == [100, 200, 300, 400] for c in curves)
    again = json.loads(invoke(*args).stdout)
    assert again["runs_computed"] == 0 and again["rows"] == doc["rows"]
    report = json.loads(invoke("report", "--json", *where).stdout)
    assert report["train"][0]["rows"] == doc["rows"]


def test_a_tabular_learner_on_the_dsn_environment(paths) -> None:
    """The DSN's own ParallelEnv has integer states: CMARL-CD learns from them."""
    _, _, where = paths
    result = invoke(
        "train", "--env", "cmarlcd.games.sensor_network:SensorNetworkEnv",
        "--algorithms", "cmarl-cd", "--episodes", "300", "--runs", "1",
        "--eval-episodes", "10", "--curve-points", "2", "--json", *where,
    )  # fmt: skip
    assert result.exit_code == 0, result.stderr
    rows = {r["algorithm"]: r for r in json.loads(result.stdout)["rows"]}
    assert set(rows) == {"random", "cmarl-cd"}


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--env", "tests.tiny_env"], "--env"),  # no factory
        (["--env", "no_such_module:make"], "--env"),
        (["--env", "tests.tiny_env:nothing"], "--env"),
        (["--env", "tests.tiny_env:NOT_A_FACTORY"], "--env"),
        (["--env", TINY, "--env-kwargs", '{"continuous": true}'], "--env"),
        (["--env", TINY, "--env-kwargs", '{"colour": 1}'], "--env"),
        (["--env", TINY, "--env-kwargs", "{nope"], "--env-kwargs"),
        (["--env", TINY, "--env-kwargs", "[1]"], "--env-kwargs"),
        (["--env", TINY, "--algorithms", "cmarl-cd"], "--algorithms"),  # vector states
        (["--env", TINY, "--reward", "max"], "--reward"),
        (["--env", TINY, "--inputs", "pixels"], "--inputs"),
        (["--env", TINY, "--episodes", "0"], "--episodes"),
        (["--env", TINY, "--runs", "0"], "--runs"),
        (["--env", TINY, "--curve-points", "0"], "--curve-points"),
        (["--env", TINY, "--runs", "1000000000"], "--runs"),  # refused before planning
        (["--env", TINY, "--envs", "0"], "--envs"),
        (["--env", TINY, "--envs", "100000"], "--envs"),
        (["--env", "tests.tiny_env:make_disagreeing", "--envs", "2"], "--envs"),
        (["--env", TINY, "--env-kwargs", '{"state": "none"}'], "--inputs"),  # no state()
        (["--env", TINY, "--inputs", "own-observations"], "--inputs"),  # not for tables
        (
            ["--env", TINY, "--env-kwargs", '{"state": "integer"}', "--algorithms", "vdn"],
            "--algorithms",
        ),  # a one-hot state of unknown count
    ],
)
def test_bad_input_is_one_line(paths, args, option) -> None:
    store, figures, where = paths
    result = invoke("train", "--algorithms", "cmarl-cd", *where, *args)
    assert_rejected_cleanly(result, option, store, figures)


@pytest.mark.parametrize(
    "design", ["shares-range-shared-refresh", "shares-range-shared-refresh-slow-td-standardised"]
)
def test_settings_only_the_compiled_loop_runs_are_refused_on_any_env(paths, design) -> None:
    """``--env`` plays through the object API, which runs neither the returns recomputed
    at each target copy nor the standardised rewards: one line, nothing stored."""
    pytest.importorskip("torch")
    store, figures, where = paths
    args = ("--env", TINY, "--set", f"deep-cmarl-cd.design={design}")
    result = invoke("train", "--algorithms", "deep-cmarl-cd", *where, *args)
    assert_rejected_cleanly(result, "--set", store, figures)
    assert "is run by the compiled loop only (--game NAME:TASK)" in result.stderr


def test_list_arguments_are_stored_and_reported(paths) -> None:
    """A factory argument that is a list reads back (as a tuple) and ``report`` groups it."""
    _, _, where = paths
    args = ("--env", TINY, "--env-kwargs", '{"labels": [1, 2], "state": "integer"}',
            "--algorithms", "cmarl-cd", "--episodes", "30", "--runs", "1",
            "--eval-episodes", "5", "--curve-points", "2", "--json", *where)  # fmt: skip
    result = invoke("train", *args)
    assert result.exit_code == 0, result.stderr
    report = invoke("report", "--json", *where)
    assert report.exit_code == 0, report.stderr
    assert json.loads(report.stdout)["train"][0]["env_kwargs"] == {
        "labels": [1, 2],
        "state": "integer",
    }


def test_a_config_error_survives_a_worker() -> None:
    """Raised in a worker process, it must come back whole (one line, not a broken pool)."""
    import pickle

    from cmarlcd.errors import ConfigError

    error = pickle.loads(pickle.dumps(ConfigError("inputs", "no state()")))
    assert (error.parameter, error.message) == ("inputs", "no state()")


@pytest.mark.parametrize("copies", [1, 4])
def test_settings_read_back_to_themselves(copies: int) -> None:
    """Runs of one copy are stored without ``envs`` (as every run made before it
    existed), runs of several with it."""
    sweep = envs.EnvSweep(TINY, (), 10, 1, 5, env_kwargs=(("actions", 3),), envs=copies)
    for spec in sweep.specs():
        settings = settings_of(spec)
        assert settings.to_config() == json.loads(spec.config_json)
        assert settings.env_kwargs == (("actions", 3),) and settings.envs == copies
        assert ("envs" in json.loads(spec.config_json)) == (copies > 1)


def test_copies_played_at_once_end_to_end(paths) -> None:
    """``--envs 3``: deep CMARL-CD still finds the optimum, the runs are stored with their
    copies (apart from one-copy runs), the report says how many, a second call computes
    nothing."""
    pytest.importorskip("torch")
    store, _, where = paths
    args = (
        "train", "--env", TINY, "--algorithms", "deep-cmarl-cd", "--episodes", "300",
        "--runs", "1", "--eval-episodes", "6", "--curve-points", "2", "--envs", "3",
        "--json", *where, "--set", "deep-cmarl-cd.batch_size=32,deep-cmarl-cd.train_every=3",
    )  # fmt: skip
    result = invoke(*args)
    assert result.exit_code == 0, result.stderr
    rows = {r["algorithm"]: r for r in json.loads(result.stdout)["rows"]}
    assert rows["deep-cmarl-cd"]["mean_return"] == 3.0
    with ResultStore(store) as db:
        assert {r.metrics["curve"][-1][0] for r in db.records(envs.EXPERIMENT)} == {300}
        assert {json.loads(r.key.config)["envs"] for r in db.records(envs.EXPERIMENT)} == {3}
    assert json.loads(invoke(*args).stdout)["runs_computed"] == 0
    report = invoke("report", *where)
    assert "3 copies at once" in report.stdout


#: Fixed-seed runs of ``train`` (tests/data): the file, and the ``--set`` that gives today
#: the settings of the version that stored it.
GOLDEN_TRAIN_RUNS = {
    # 0.5.x, before copies of an environment were played at once, and before the deep
    # learners' step was a setting: they took autograd's step (their default then)
    "train-before-copies.json": "vdn.step=autograd,deep-cmarl-cd.step=autograd",
    # 0.6.0: the deep learners at step "auto" (the fused step on the CPU), the default
    "train-step-auto.json": None,
}


@pytest.mark.parametrize(
    "golden_file",
    [  # the runs of 0.5.x take a minute more; their reading is also a unit test (runs)
        pytest.param("train-before-copies.json", marks=pytest.mark.slow),
        "train-step-auto.json",
    ],
)
def test_one_copy_plays_the_stored_fixed_seed_runs(paths, golden_file: str) -> None:
    """The same command at ``--envs 1`` gives the stored runs (the same config, so the
    same seeds, and the same learning curve, number for number): those of the version
    before copies were played, and those of the fused step (``auto`` on the CPU)."""
    pytest.importorskip("torch")
    from pathlib import Path

    golden = json.loads((Path(__file__).parents[1] / "data" / golden_file).read_text())
    store, _, where = paths
    named = GOLDEN_TRAIN_RUNS[golden_file]
    settings = ["--set", named] if named else []
    command = [*golden["command"].split()[1:], "--envs", "1", *settings]
    result = invoke(*command, "--json", *where)
    assert result.exit_code == 0, result.stderr
    with ResultStore(store) as db:
        stored = {r.key.algorithm: r for r in db.records(envs.EXPERIMENT)}
    assert set(stored) == set(golden["runs"])
    for algorithm, run in golden["runs"].items():
        assert json.loads(stored[algorithm].key.config) == run["config"]
        assert stored[algorithm].metrics["curve"] == run["curve"]


def test_a_deep_cmarl_cd_that_kept_nothing_is_named_in_the_report(paths) -> None:
    """Every reward negative: under ``estimate`` the memory stays empty and the report
    says so; under ``estimate-once-kept`` it learns, and nothing is said."""
    pytest.importorskip("torch")
    _, _, where = paths
    base = ("train", "--env", TINY, "--env-kwargs", '{"offset": -1}', "--algorithms",
            "deep-cmarl-cd", "--episodes", "20", "--runs", "2", "--eval-episodes", "2",
            "--curve-points", "1", *where)  # fmt: skip
    result = invoke(*base)
    assert result.exit_code == 0, result.stderr
    assert "2 of 2 runs kept nothing to learn from" in result.stdout
    fixed = invoke(*base, "--set", "deep-cmarl-cd.unseen_record=estimate-once-kept")
    assert fixed.exit_code == 0, fixed.stderr
    assert "kept nothing" not in fixed.stdout


def test_a_budget_of_steps_end_to_end(paths) -> None:
    """``--steps``: the curve's points at steps 300, 600 and 900 (the tiny game's
    episodes last 3 steps, so each budget is met exactly), the runs stored with their
    unit, the report in steps; ε of a deep learner read per step of the budget."""
    pytest.importorskip("torch")
    from cmarlcd.learners.deep.config import DeepConfig, epsilon

    store, _, where = paths
    args = (
        "train", "--env", TINY, "--algorithms", "vdn", "--steps", "900", "--runs", "1",
        "--eval-episodes", "4", "--curve-points", "3", "--envs", "2", "--json", *where,
    )  # fmt: skip
    result = invoke(*args)
    assert result.exit_code == 0, result.stderr
    with ResultStore(store) as db:
        records = list(db.records(envs.EXPERIMENT))
    assert {json.loads(r.key.config)["unit"] for r in records} == {"steps"}
    for record in records:
        assert [point[0] for point in record.metrics["curve"]] == [300, 600, 900]
    doc = json.loads(result.stdout)
    mean_curve = np.mean(
        [[p[1] for p in r.metrics["curve"]] for r in records if r.key.algorithm == "vdn"], axis=0
    )
    assert doc["field"]["VDN"]["max_return"] == pytest.approx(mean_curve.max())
    assert doc["field"]["VDN"]["average_return"] == pytest.approx(mean_curve.mean())
    assert "random policy" not in {k.lower() for k in doc["field"]}
    report = invoke("report", *where).stdout
    assert "900 environment steps" in report and "The field's figures" in report
    config = DeepConfig()  # step 450 of 900 is where episode 450 of 900 is
    assert epsilon(1, 900, config, 450, by_steps=True) == epsilon(450, 900, config)
    assert epsilon(1, 900, config, 450, by_steps=True) < epsilon(1, 900, config, 450)


@pytest.mark.parametrize("learner", ["vdn", "deep-cmarl-cd"])
def test_the_evaluation_before_learning_changes_nothing_a_deep_learner_learns(learner) -> None:
    """``eval_at_start``: one more point at 0, and the same later points, number for number
    (the evaluation plays copies of its own, and a deep learner acts greedily without a
    draw); the runs are new ones (the setting is in their identity only when on)."""
    pytest.importorskip("torch")
    from cmarlcd import registry

    config = registry.require_learner(learner)
    runs = {}
    for at_start in (False, True):
        settings = envs.EnvRun(
            TINY, (), config, 120, 3, curve_points=2, inputs="observations", envs=2,
            unit="steps", eval_at_start=at_start,
        )  # fmt: skip
        runs[at_start] = envs.run(settings, np.random.SeedSequence(7))["curve"]
        assert ("eval_at_start" in settings.to_config()) == at_start
    assert [point[0] for point in runs[True]] == [0, 60, 120]
    assert runs[True][1:] == runs[False]
