"""The outside anchor's script (benchmarks/anchors/): it needs its own environment to
train, so CI checks only that it imports without BenchMARL, shows ``--help``, refuses bad
budgets in one line, and computes its intervals right."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).parents[1] / "benchmarks/anchors/benchmarl_simple_spread.py"


def anchor():
    spec = importlib.util.spec_from_file_location("anchor", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, check=False
    )


def test_help_without_benchmarl_installed() -> None:
    done = run("--help")
    assert done.returncode == 0, done.stderr
    assert "--frames" in done.stdout and "--seeds" in done.stdout


@pytest.mark.parametrize(
    "args", [["--frames", "1.01M"], ["--eval-every", "5000"], ["--frames", "lots"]]
)
def test_bad_budgets_are_one_line(args: list[str], tmp_path: Path) -> None:
    done = run(*args, "--out", str(tmp_path))
    assert done.returncode == 2
    assert done.stderr.startswith("error: ") and done.stderr.count("\n") == 1
    assert not (tmp_path / "runs").exists()


def test_budgets_and_intervals() -> None:
    module = anchor()
    assert module.budget("1.02M") == 1_020_000 and module.budget("102k") == 102_000
    mean, half = module.interval([1.0, 2.0, 3.0])  # sd 1, t(2 df) = 4.303
    assert mean == 2.0 and half == pytest.approx(4.303 / 3**0.5)
    assert module.interval([5.0]) == (5.0, 0.0)


def test_the_equivalent_command_makes_the_runs_of_the_cmarl_cd_side() -> None:
    """``cmarl-cd train`` given the printed command builds the very settings (so the
    seeds) the script runs."""
    import shlex

    from cmarlcd import registry
    from cmarlcd.cli.options import apply_settings
    from cmarlcd.cli.train import parse_env_kwargs

    module = anchor()
    words = shlex.split(module.equivalent_command(1_020_000, 102_000, 50))
    option = {words[k]: words[k + 1] for k in range(2, len(words) - 1, 2)}
    configs = tuple(registry.require_learner(n) for n in ("vdn", "qmix"))
    learners = dict(zip(("vdn", "qmix"), apply_settings(option["--set"], configs), strict=True))
    for name, learner in learners.items():
        ours = module.ours_settings(name, 1_020_000, 102_000, 50)
        assert ours.learner == learner
        assert ours.env_kwargs == parse_env_kwargs(option["--env-kwargs"])
        assert (ours.episodes, ours.curve_points, ours.eval_episodes) == (40_800, 10, 50)
        assert (ours.reward, ours.inputs, ours.envs) == ("mean", "own-observations", 10)


def test_runs_of_another_budget_are_not_mixed_in(tmp_path: Path) -> None:
    """A study resumed on an ``--out`` that holds runs of another budget stops in one
    line before it trains anything."""
    runs = tmp_path / "runs"
    runs.mkdir()
    curve = [[102_000 * k, -20.0] for k in range(1, 11)]
    stored = {"side": "cmarl-cd", "algorithm": "vdn", "seed": 0, "curve": curve}
    (runs / "cmarl-cd-vdn-seed0.json").write_text(__import__("json").dumps(stored))
    done = run("--frames", "2.04M", "--eval-every", "204k", "--out", str(tmp_path))
    assert done.returncode == 2 and done.stderr.count("\n") == 1
    assert "another budget" in done.stderr
    assert "runs already" not in done.stdout


def test_the_compiled_command_makes_the_runs_of_the_compiled_side() -> None:
    """``cmarl-cd train --game`` given the printed command builds the very settings (so
    the seeds) the compiled side runs."""
    import shlex

    from cmarlcd import registry
    from cmarlcd.cli.options import apply_settings
    from cmarlcd.experiments import games

    module = anchor()
    words = shlex.split(module.compiled_command(1_020_000, 102_000, 50))
    option = {words[k]: words[k + 1] for k in range(2, len(words) - 1, 2)}
    family, rules = games.parse_game(option["--game"])
    configs = tuple(registry.require_learner(n) for n in ("vdn", "qmix"))
    learners = dict(zip(("vdn", "qmix"), apply_settings(option["--set"], configs), strict=True))
    for name, learner in learners.items():
        ours = module.compiled_settings(name, 1_020_000, 102_000, 50)
        assert ours.learner == learner
        assert ours.options == family.options(rules, option["--inputs"])
        assert ours.checkpoints == (int(option["--episodes"]),) == (40_800,)
        assert (ours.curve_points, ours.eval_episodes) == (10, 50)
        assert (int(option["--curve-points"]), int(option["--eval-episodes"])) == (10, 50)


EPYMARL = Path(__file__).parents[1] / "benchmarks/anchors/epymarl_lbf.py"


def epymarl_anchor():
    """The EPyMARL anchor's script as a module."""
    spec = importlib.util.spec_from_file_location("epymarl_anchor", EPYMARL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def failing_runs(module, monkeypatch) -> list[list[str]]:
    """Every command the anchor hands to ``subprocess.run`` (answered as failed, so the
    anchor stops there), in order."""
    seen: list[list[str]] = []

    def fake_run(command, **kwargs):
        seen.append(command)
        return subprocess.CompletedProcess(command, 1)

    monkeypatch.setattr(module.subprocess, "run", fake_run)
    return seen


def test_the_epymarl_anchor_shows_its_help_without_epymarl() -> None:
    done = subprocess.run(
        [sys.executable, str(EPYMARL), "--help"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert "--epymarl" in done.stdout and "--steps" in done.stdout


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--tasks", "9x9"], "--tasks: 9x9"),
        (["--algorithms", "iql,coma"], "--algorithms: unknown 'coma'"),
        (["--steps", "1M", "--eval-interval", "300k"], "must divide --steps"),
        ([], "--epymarl: give the path"),
        (["--epymarl", "."], "holds no src/main.py"),
        (["--parallel", "0"], "--parallel: must be >= 1"),
        (["--agent", "gru"], "--agent: unknown 'gru'"),
        (["--ours", "twin"], "--ours: unknown 'twin'"),
        (["--layers", "0"], "--layers: must be >= 1 (got 0)"),
        (["--hypernet-layers", "3"], "--hypernet-layers: must be 1 or 2 (got 3)"),
        (["--step", "fast"], "--step: unknown 'fast'"),
        (["--rounds", "0"], "--rounds: must be >= 1"),
        (["--speed", "--report-only"], "give one"),
    ],
)
def test_the_epymarl_anchor_refuses_bad_input_in_one_line(args, says, tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, str(EPYMARL), *args, "--out", str(tmp_path / "out")],
        capture_output=True, text=True, check=False, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert says in done.stderr and done.stderr.count("\n") == 1, done.stderr
    assert not (tmp_path / "out").exists()


def test_the_epymarl_anchor_reads_sacreds_numbers_and_compares_the_kth_tests(tmp_path) -> None:
    """Two hand-made EPyMARL runs and a cmarl-cd command's curves: the figures are the
    field's of the k-th points of each side, the verdict against EPyMARL's interval."""
    spec = importlib.util.spec_from_file_location("epymarl_anchor", EPYMARL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.value({"py/object": "numpy.float64", "value": 0.25}) == 0.25
    protocol = {"tasks": ["8x8-2p-2f-coop"], "algorithms": ["vdn"], "sides": ["epymarl"],
                "seeds": 2, "steps": 100, "eval_interval": 50, "eval_episodes": 5,
                "agent": "rnn", "ours": "shared"}  # fmt: skip
    for seed, returns in enumerate(([0.0, 0.2, 0.4], [0.0, 0.4, 0.6])):
        curve = [[t, r] for t, r in zip((50, 100, 150), returns, strict=True)]
        module.write(module.job_path(tmp_path, "epymarl", ("8x8-2p-2f-coop", "vdn", seed)), {
            "protocol": module.protocol_of(protocol, "epymarl"), "seconds": 2.0,
            "steps_trained": 100, "curve": curve,
        })  # fmt: skip
    ours = module.cmarlcd_job("8x8-2p-2f-coop", protocol)
    module.write(module.job_path(tmp_path, "cmarl-cd", ours), {
        "protocol": module.protocol_of(protocol, "cmarl-cd"), "seconds": 1.0,
        "curves": {"vdn": [[0.0, 0.1, 0.3], [0.0, 0.3, 0.3]]},
    })  # fmt: skip
    summary = module.summarise(tmp_path, protocol)
    (row,) = summary["pairs"]
    assert row["epymarl"]["max_return"] == pytest.approx(0.5)  # the last test's mean
    assert row["epymarl"]["max_return_at"] == 100  # the k-th nominal point
    assert row["epymarl"]["average_return"] == pytest.approx((0.6 + 1.0) / 6)
    assert row["cmarl-cd"]["max_return"] == pytest.approx(0.3)
    half = 12.706 * 0.1  # t(1 df) x sd / sqrt(2): sd of 0.4 and 0.6 is 0.1 x sqrt(2)
    assert row["epymarl"]["max_return_low"] == pytest.approx(0.5 - half, abs=1e-3)
    assert row["verdict"] == "within or above"  # 0.3 >= 0.5 - 1.271
    assert summary["steps_per_second"] == {"cmarl-cd": 200.0, "epymarl": 50.0}
    assert summary["ratio"] == 4.0
    # EPyMARL's feed-forward agents are other runs, kept apart from its GRU agents'
    assert module.summarise(tmp_path, {**protocol, "agent": "mlp"})["pairs"][0]["curves"] == {
        "cmarl-cd": [[0.0, 0.1, 0.3], [0.0, 0.3, 0.3]], "epymarl": []}  # fmt: skip
    assert module.AGENTS["mlp"] == ("use_rnn=False",)
    # and cmarl-cd's per-agent networks are other jobs than its shared one's
    per_agent = module.summarise(tmp_path, {**protocol, "ours": "per-agent"})["pairs"][0]
    assert per_agent["curves"]["cmarl-cd"] == [] and len(per_agent["curves"]["epymarl"]) == 2
    # with a seed of EPyMARL's still to come, its interval judges nothing yet
    three = {**protocol, "seeds": 3}
    module.write(module.job_path(tmp_path, "cmarl-cd", ours), {
        "protocol": module.protocol_of(three, "cmarl-cd"), "seconds": 1.0,
        "curves": {"vdn": [[0.0, 0.1, 0.3]] * 3},
    })  # fmt: skip
    three = module.summarise(tmp_path, three)["pairs"][0]
    assert three["verdict"] == "not yet (2 of 3 EPyMARL seeds)"


def test_the_epymarl_anchor_runs_each_job_once_however_many_at_a_time(monkeypatch) -> None:
    spec = importlib.util.spec_from_file_location("epymarl_anchor", EPYMARL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    protocol = {"tasks": ["8x8-2p-2f-coop", "10x10-3p-3f"], "algorithms": ["iql", "vdn"],
                "seeds": 2, "agent": "mlp"}  # fmt: skip
    todo = module.jobs("epymarl", protocol)
    assert todo[:4] == [(t, a, 0, "mlp") for t in protocol["tasks"] for a in ("iql", "vdn")]
    done: list[tuple] = []
    monkeypatch.setattr(module, "run_job", lambda side, job, *rest: done.append(job))
    for parallel in (1, 3):
        done.clear()
        module.run_jobs("epymarl", todo, protocol, Path("."), type("A", (), {"parallel": parallel}))
        assert sorted(done) == sorted(todo) and len(done) == 8


def launcher_module():
    path = EPYMARL.with_name("epymarl_agents.py")
    spec = importlib.util.spec_from_file_location("epymarl_agents", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_one_layer_agent_is_one_hidden_layer_by_hand() -> None:
    """EPyMARL's agent with cmarl-cd's model class: Q = W2 ReLU(W1 x + b1) + b2, and the
    hidden state it is handed comes back as it was (it carries none)."""
    import torch

    module = launcher_module()
    args = type("Args", (), {"hidden_dim": 2, "n_actions": 2})
    agent = module.OneHiddenLayerAgent(3, args)
    assert sorted(name for name, _ in agent.named_parameters()) == [
        "fc1.bias", "fc1.weight", "fc2.bias", "fc2.weight"
    ]  # fmt: skip
    with torch.no_grad():
        agent.fc1.weight.copy_(torch.tensor([[1.0, 0.0, -1.0], [0.5, 2.0, 0.0]]))
        agent.fc1.bias.copy_(torch.tensor([0.0, -1.0]))
        agent.fc2.weight.copy_(torch.tensor([[1.0, -1.0], [2.0, 0.5]]))
        agent.fc2.bias.copy_(torch.tensor([0.25, 0.0]))
    x = torch.tensor([[1.0, 1.0, 3.0]])  # hidden: ReLU(-2) = 0, ReLU(0.5 + 2 - 1) = 1.5
    hidden = torch.full((1, 2), 7.0)
    q, kept = agent(x, hidden)
    assert q.tolist() == [[0.25 - 1.5, 0.75]] and torch.equal(kept, hidden)
    assert agent.init_hidden().shape == (1, 2)


def test_the_launcher_registers_the_agent_and_runs_epymarls_main(tmp_path: Path) -> None:
    """On a stand-in EPyMARL tree: ``src`` on the path, the agent in its registry, and
    ``src/main.py`` run as ``__main__`` with the command line it was given."""
    agents = tmp_path / "src" / "modules" / "agents"
    agents.mkdir(parents=True)
    (tmp_path / "src" / "modules" / "__init__.py").write_text("")
    (agents / "__init__.py").write_text("REGISTRY = {'rnn': object}\n")
    (tmp_path / "src" / "main.py").write_text(
        "import sys\nfrom modules.agents import REGISTRY\n"
        "if __name__ == '__main__':\n"
        "    print(sorted(REGISTRY), REGISTRY['one_layer'].__name__, sys.argv)\n"
    )
    launcher = EPYMARL.with_name("epymarl_agents.py")
    done = subprocess.run(
        [sys.executable, str(launcher), "src/main.py", "--config=iql", "with", "agent=one_layer"],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == (
        "['one_layer', 'rnn'] OneHiddenLayerAgent ['src/main.py', '--config=iql', 'with', "
        "'agent=one_layer']"
    )
    missing = subprocess.run(
        [sys.executable, str(launcher), "src/nothing.py"], cwd=tmp_path, capture_output=True,
        text=True, check=False,
    )  # fmt: skip
    assert missing.returncode == 1 and missing.stderr.startswith("usage: ")


@pytest.mark.parametrize("agent", ["mlp", "one-layer"])
def test_the_epymarl_command_of_each_agent(agent: str, monkeypatch, tmp_path: Path) -> None:
    module = epymarl_anchor()
    seen = failing_runs(module, monkeypatch)
    protocol = {"steps": 100, "eval_interval": 50, "eval_episodes": 10, "agent": agent}
    with pytest.raises(SystemExit):
        module.epymarl("8x8-2p-2f-coop", "iql", 0, protocol, tmp_path, tmp_path / "l.log", True)
    (command,) = seen
    launched = command[1] == str(EPYMARL.with_name("epymarl_agents.py").resolve())
    assert launched == (agent == "one-layer")
    assert command[1 + launched] == "src/main.py" and "use_rnn=False" in command
    assert ("agent=one_layer" in command) == (agent == "one-layer")


@pytest.mark.parametrize(
    ("ours", "layers", "hyper", "step"),
    [("shared", 1, 1, "auto"), ("shared", 2, 1, "auto"), ("per-agent", 2, 1, "auto"),
     ("shared", 2, 2, "auto"), ("shared", 2, 2, "fused")],
)  # fmt: skip
def test_cmarl_cds_command_and_job_of_each_form(ours, layers, hyper, step, monkeypatch, tmp_path):
    """Our side's settings follow --ours, --layers, --hypernet-layers and --step, and each
    form is a job of its own (EPyMARL's feed-forward agent has two hidden layers, its QMIX
    two-layer hypernetworks: --agent mlp --layers 2 --hypernet-layers 2)."""
    module = epymarl_anchor()
    seen = failing_runs(module, monkeypatch)
    protocol = {"steps": 100, "eval_interval": 50, "eval_episodes": 10, "seeds": 1,
                "algorithms": ["iql", "qmix"], "ours": ours, "layers": layers,
                "hypernet_layers": hyper, "step": step}  # fmt: skip
    with pytest.raises(SystemExit):
        module.ours("8x8-2p-2f-coop", protocol, tmp_path, tmp_path / "l.log")
    (command,) = seen
    settings = command[command.index("--set") + 1].split(",") if "--set" in command else []
    expected = [f"{learner}.{s}" for learner in ("deep-iql", "qmix")
                for s in (["share=true"] if ours == "shared" else [])
                + ([f"hidden_layers={layers}"] if layers > 1 else [])
                + (["hypernet_layers=2"] if hyper == 2 and learner == "qmix" else [])
                + ([f"step={step}"] if step != "auto" else [])]  # fmt: skip
    assert settings == expected
    job = module.cmarlcd_job("8x8-2p-2f-coop", protocol)
    assert job == ("8x8-2p-2f-coop", *(("shared",) if ours == "shared" else ()),
                   *((f"layers{layers}",) if layers > 1 else ()),
                   *(("hyper2",) if hyper == 2 else ()),
                   *((step,) if step != "auto" else ()))  # fmt: skip


def test_the_epymarl_speed_run_alternates_the_sides_and_takes_medians(tmp_path: Path) -> None:
    """Stand-ins for the two sides' launchers and a clock: EPyMARL's 1,000 steps take 2 s
    every round (500 a second: its budget, not the step of its last test, 50); cmarl-cd's
    3 seeds x 1,000 take 0.5, 1 and 0.25 s (6,000, 3,000 and 12,000 a second): medians
    500 and 6,000, ratio 12. Each side runs the task's budget with one short test,
    cmarl-cd into a fresh folder each round."""
    sys.path.insert(0, str(EPYMARL.parent))
    from epymarl_speed import TEST_EPISODES, measure, speed_table

    calls = []
    anchor = types.SimpleNamespace(
        epymarl=lambda task, algorithm, seed, protocol, *rest: calls.append(
            ("epymarl", algorithm, seed, protocol)) or {"steps_trained": 50},
        ours=lambda task, protocol, where, log: calls.append(
            ("cmarl-cd", where, protocol)) or {"curves": {}},
        machine=lambda: {},
    )  # fmt: skip
    durations = iter([2.0, 0.5, 2.0, 1.0, 2.0, 0.25])
    ticks = iter(np.cumsum([0.0, *(x for d in durations for x in (d, 0.0))]))
    protocol = {"tasks": ["8x8-2p-2f-coop", "10x10-3p-3f"], "algorithms": ["vdn"], "seeds": 3,
                "steps": 1_000, "eval_interval": 500, "eval_episodes": 100, "agent": "mlp",
                "ours": "shared"}  # fmt: skip
    result = measure(anchor, protocol, tmp_path, tmp_path, 3, False, clock=lambda: next(ticks))
    assert [c[0] for c in calls] == ["epymarl", "cmarl-cd"] * 3
    assert result["medians"]["vdn"] == pytest.approx(
        {"epymarl": 500.0, "cmarl-cd": 6_000.0, "ratio": 12.0}
    )
    assert [r["cmarl-cd"]["rate"] for r in result["runs"]] == pytest.approx([6e3, 3e3, 12e3])
    folders = [c[1] for c in calls if c[0] == "cmarl-cd"]
    assert len(set(folders)) == 3
    for call in calls:
        run = call[-1]
        assert (run["eval_interval"], run["eval_episodes"]) == (1_000, TEST_EPISODES)
        assert run["algorithms"] == ["vdn"]
    assert result["task"] == "8x8-2p-2f-coop"
    assert "| vdn | 500 | 6,000 | 12.0x |" in speed_table(result)
