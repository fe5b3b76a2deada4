"""The outside anchor: BenchMARL's VDN and QMIX beside cmarl-cd's, on MPE simple_spread.

Both sides train on the same task (3 agents, local_ratio 0.5, 25 steps, discrete
actions) with the same hyper-parameters (:data:`SHARED`, printed with every run), the
same frame budget and the same seeds count, and are evaluated greedily at the same frame
counts. A frame is one environment step (every agent acts once); a return is the mean
over agents of each agent's summed reward (BenchMARL's "episode reward mean"; cmarl-cd's
team reward with ``reward="mean"``). A third side, ``cmarl-cd-compiled``
(``--sides benchmarl,cmarl-cd,cmarl-cd-compiled``), runs cmarl-cd's with the same settings
on its compiled simple_spread (``train --game simple_spread:reward=mean --inputs
own-observations``), one copy of the game per seed; its time is not split into
collection and training.

It needs its own environment (BenchMARL 1.5.2 and torchrl, never the package's
dependencies): ``bash benchmarks/anchors/install.sh VENV``. Each (side, algorithm, seed)
is one job, written to ``OUT/runs/`` as it ends, so an interrupted run resumes where it
stopped; the table, ``OUT/anchor.png`` and ``OUT/anchor.json`` come from whatever is
there. ``--help`` works without BenchMARL installed.

    python benchmarks/anchors/benchmarl_simple_spread.py --frames 1.02M --seeds 3
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

SIDES = ("benchmarl", "cmarl-cd", "cmarl-cd-compiled")
SIDE_NAMES = {
    "benchmarl": "BenchMARL 1.5.2",
    "cmarl-cd": "cmarl-cd",
    "cmarl-cd-compiled": "cmarl-cd, compiled game",
}
ALGORITHMS = ("vdn", "qmix")
STEPS_PER_EPISODE = 25
COLLECTED_PER_BATCH = 6_000
MAX_POINTS = 100
"""The most evaluations a curve has (``cmarl-cd train``'s limit)."""
"""BenchMARL collects this many frames, then trains (its default)."""

#: The hyper-parameters both sides share: BenchMARL's off-policy defaults, except where
#: one side cannot express the other's (each such change named in ``changed``).
SHARED: dict[str, Any] = {
    "gamma": 0.99,
    "lr": 5e-5,
    "adam_eps": 1e-8,
    "grad_clipping": None,
    "eps_start": 0.8,
    "eps_end": 0.01,
    "eps_anneal_fraction": 1 / 3,
    "agent_network": "per agent (no sharing), own observation -> 256 ReLU -> actions",
    "qmix_mixer": "hypernetworks on the state, 32 ELU units, V(s) of 32 ReLU units",
    "replay": "1,000,000 transitions, uniform with replacement",
    "batch_size": 128,
    "frames_per_gradient_step": 6,
    "target_update": "hard copy every 200 gradient steps (1,200 frames)",
    "team_reward": "mean of the agents' rewards",
    "envs_per_side": 10,
    "changed": {
        "adam_eps": "BenchMARL 1e-6 -> 1e-8 (PyTorch's default, which cmarl-cd uses)",
        "grad_clipping": "BenchMARL clips the norm at 5 -> none (cmarl-cd does not clip)",
        "agent_network": "BenchMARL [256, 256] Tanh, shared -> [256] ReLU, per agent "
        "(cmarl-cd's networks have one hidden ReLU layer and no sharing)",
        "target_update": "BenchMARL soft, tau 0.005 -> hard every 200 steps (cmarl-cd "
        "copies; 200 steps is the soft update's time constant)",
    },
    "differences_left": [
        "BenchMARL collects 6,000 frames, then takes 1,000 gradient steps; cmarl-cd takes "
        "one step every 6 frames",
        "BenchMARL starts learning after its first 6,000 frames; cmarl-cd once 128 "
        "transitions are stored",
        "BenchMARL's epsilon falls once per 6,000 frames; cmarl-cd's once per episode",
    ],
}
OURS = dict(
    hidden=256, mixer_hidden=32, buffer_size=1_000_000, batch_size=128, train_every=6,
    target_every=1_200, lr=5e-5, gamma=0.99, eps_start=0.8, eps_end=0.01,
    anneal_fraction=1 / 3, eps_after=0.01,
)  # fmt: skip
ENV = "mpe2.simple_spread_v3:parallel_env"
#: Sorted, as ``cmarl-cd train --env-kwargs`` keeps them (they are part of a run's seed).
ENV_KWARGS = (("N", 3), ("continuous_actions", False), ("local_ratio", 0.5), ("max_cycles", 25))


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        frames, eval_every = budget(args.frames), budget(args.eval_every)
        check(frames, eval_every, args.seeds)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    unknown = [side for side in args.sides.split(",") if side not in SIDES]
    if unknown:
        print(
            f"error: --sides: unknown side {unknown[0]!r} (sides: {', '.join(SIDES)})",
            file=sys.stderr,
        )
        return 2
    out = Path(args.out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    if args.job:  # one run, in a process of its own (see below)
        side, algorithm, seed = args.job.split(":")
        result = JOBS[side](algorithm, int(seed), frames, eval_every, args.eval_episodes)
        data = {"side": side, "algorithm": algorithm, "seed": int(seed), **result}
        write(run_path(out, side, algorithm, int(seed)), data)
        return 0
    other = [p.name for p in stored_runs(out) if not same_budget(p, frames, eval_every)]
    if other:
        print(
            f"error: {out / 'runs'} holds runs of another budget ({other[0]}, …): give "
            f"another --out",
            file=sys.stderr,
        )
        return 2
    print("shared hyper-parameters:", json.dumps(SHARED, indent=1))
    if args.check_task:
        print(check_task())
    jobs = [
        (side, algorithm, seed)
        for seed in range(args.seeds)
        for algorithm in args.algorithms.split(",")
        for side in args.sides.split(",")
    ]
    todo = [j for j in jobs if not run_path(out, *j).exists()]
    print(f"{len(jobs) - len(todo)} of {len(jobs)} runs already in {out / 'runs'}")
    for k, (side, algorithm, seed) in enumerate(todo, 1):
        started = time.perf_counter()
        # each run in a fresh process: its memory is freed and nothing it patches stays
        command = [sys.executable, __file__, *(argv if argv is not None else sys.argv[1:])]
        done = subprocess.run([*command, "--job", f"{side}:{algorithm}:{seed}"], check=False)
        if done.returncode:
            print(f"error: the {side} run of {algorithm}, seed {seed}, failed", file=sys.stderr)
            return 1
        seconds = time.perf_counter() - started
        print(f"[{k}/{len(todo)}] {side} {algorithm} seed {seed}: {seconds:.0f} s", flush=True)
    summary = summarise(out, frames)
    print(table(summary))
    figure(summary, out / "anchor.png")
    write(out / "anchor.json", summary)
    print(f"table: {out / 'anchor.json'}; figure: {out / 'anchor.png'}")
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", default="1.02M", help="frames per run (default 1.02M)")
    p.add_argument("--eval-every", default="102k", help="frames between greedy evaluations")
    p.add_argument("--eval-episodes", type=int, default=50, help="episodes per evaluation")
    p.add_argument("--seeds", type=int, default=3, help="seeds per side and algorithm")
    p.add_argument("--algorithms", default="vdn,qmix", help="comma list of vdn, qmix")
    p.add_argument(
        "--sides",
        default="benchmarl,cmarl-cd",
        help="comma list of benchmarl, cmarl-cd (mpe2) and cmarl-cd-compiled (cmarl-cd on "
        "its compiled simple_spread)",
    )
    p.add_argument("--out", default="results/anchor", help="folder of runs, table and figure")
    p.add_argument("--job", help=argparse.SUPPRESS)  # SIDE:ALGORITHM:SEED, one run
    p.add_argument(
        "--check-task", action="store_true",
        help="first check that both sides' simple_spread give the same steps",
    )  # fmt: skip
    return p


def budget(text: str) -> int:
    """``"1.02M"`` -> 1020000, ``"102k"`` -> 102000."""
    scale = {"k": 1_000, "m": 1_000_000}.get(text[-1:].lower(), 1)
    number = text[:-1] if scale > 1 else text
    try:
        return round(float(number) * scale)
    except ValueError:
        raise ValueError(f"not a number of frames: {text!r}") from None


def check(frames: int, eval_every: int, seeds: int) -> None:
    if eval_every <= 0 or eval_every % COLLECTED_PER_BATCH or frames % eval_every:
        raise ValueError(
            f"--eval-every must be a multiple of {COLLECTED_PER_BATCH} that divides --frames "
            f"(BenchMARL evaluates after whole batches); got {eval_every} and {frames}"
        )
    if eval_every % STEPS_PER_EPISODE:
        raise ValueError(f"--eval-every must be whole episodes of {STEPS_PER_EPISODE} frames")
    if frames // eval_every > MAX_POINTS:
        raise ValueError(f"at most {MAX_POINTS} evaluations (--frames / --eval-every)")
    if seeds < 1:
        raise ValueError(f"--seeds must be >= 1 (got {seeds})")


def stored_runs(out: Path) -> list[Path]:
    return sorted((out / "runs").glob("*.json"))


def same_budget(path: Path, frames: int, eval_every: int) -> bool:
    """Whether a stored run evaluated at the frame counts of this budget."""
    curve = json.loads(path.read_text())["curve"]
    return [p[0] for p in curve] == list(range(eval_every, frames + 1, eval_every))


def run_path(out: Path, side: str, algorithm: str, seed: int) -> Path:
    return out / "runs" / f"{side}-{algorithm}-seed{seed}.json"


def write(path: Path, data: dict) -> None:
    """Written whole or not at all."""
    partial = path.with_suffix(f".{os.getpid()}.part")
    partial.write_text(json.dumps(data, indent=1))
    os.replace(partial, path)


# ----------------------------------------------------------------------------- sides


def benchmarl_run(algorithm: str, seed: int, frames: int, eval_every: int, episodes: int):
    """One BenchMARL run; its own timers, summed (collection, training, evaluation)."""
    import torch
    from benchmarl.algorithms import QmixConfig, VdnConfig
    from benchmarl.environments import PettingZooTask
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.experiment.callback import Callback
    from benchmarl.models.mlp import MlpConfig

    torch.set_num_threads(1)
    config = ExperimentConfig.get_from_yaml()
    config.loggers, config.render, config.checkpoint_at_end = [], False, False
    config.create_json = True  # BenchMARL evaluates only with a logger or its json
    config.save_folder = str(Path(os.environ.get("TMPDIR", "/tmp")))
    config.max_n_frames, config.evaluation_interval = frames, eval_every
    config.evaluation_episodes, config.evaluation_deterministic_actions = episodes, True
    config.share_policy_params, config.gamma, config.lr = False, SHARED["gamma"], SHARED["lr"]
    config.adam_eps, config.clip_grad_norm, config.clip_grad_val = 1e-8, False, None
    config.soft_target_update, config.hard_target_update_frequency = False, 200
    config.exploration_eps_init, config.exploration_eps_end = 0.8, 0.01
    config.exploration_anneal_frames = frames // 3
    config.off_policy_n_envs_per_worker = SHARED["envs_per_side"]
    config.off_policy_train_batch_size = SHARED["batch_size"]
    config.off_policy_memory_size = 1_000_000
    task = PettingZooTask.SIMPLE_SPREAD.get_from_yaml()
    task.config.update({"max_cycles": 25, "N": 3, "local_ratio": 0.5})
    model = MlpConfig(
        num_cells=[256], layer_class=torch.nn.Linear, activation_class=torch.nn.ReLU,
        activation_kwargs=None, norm_class=None, norm_kwargs=None,
    )  # fmt: skip
    algo = {"vdn": VdnConfig, "qmix": QmixConfig}[algorithm].get_from_yaml()
    record = recorder(Callback)
    experiment = Experiment(
        task=task, algorithm_config=algo, model_config=model, seed=seed, config=config,
        callbacks=[record],
    )  # fmt: skip
    timers = {"collection": 0.0, "training": 0.0, "evaluation": 0.0}
    log = experiment.logger.log

    def timed_log(values: dict, step: int | None = None) -> None:
        for name in timers:
            timers[name] += float(values.get(f"timers/{name}_time", 0.0))
        log(values, step=step)

    experiment.logger.log = timed_log
    started = time.perf_counter()
    experiment.run()
    total = time.perf_counter() - started
    import benchmarl
    import torchrl

    return {
        "curve": [p for p in record.curve if p[0] % eval_every == 0],
        "seconds": {**timers, "total": total},
        "versions": {"benchmarl": benchmarl.__version__, "torchrl": torchrl.__version__},
    }


def recorder(base: type) -> Any:
    """A BenchMARL callback keeping (frames, mean return per agent) at each evaluation;
    its class is made a global of this module, as BenchMARL pickles its callbacks."""

    class Record(base):  # type: ignore[misc, valid-type]
        def __init__(self) -> None:
            super().__init__()
            self.curve: list[list[float]] = []

        def on_evaluation_end(self, rollouts) -> None:
            returns = [per_agent_return(td, self.experiment.group_map) for td in rollouts]
            self.curve.append([self.experiment.total_frames, sum(returns) / len(returns)])

    Record.__qualname__ = Record.__name__
    globals()[Record.__name__] = Record
    return Record()


def per_agent_return(rollout, group_map: dict) -> float:
    """An evaluation episode's summed reward, averaged over the agents."""
    total = sum(float(rollout.get(("next", g, "reward")).sum()) for g in group_map)
    return total / sum(len(agents) for agents in group_map.values())


def ours_run(algorithm: str, seed: int, frames: int, eval_every: int, episodes: int):
    """One cmarl-cd run, exactly as ``cmarl-cd train`` makes run ``seed`` of root seed 0
    (:func:`equivalent_command`); the time in the learner's schedule (replay draws,
    gradient steps, target copies) and in evaluation measured apart."""
    import torch

    from cmarlcd.experiments import environment as envs
    from cmarlcd.learners.deep.agent import DeepAgent
    from cmarlcd.runs import RunSpec

    torch.set_num_threads(1)
    settings = ours_settings(algorithm, frames, eval_every, episodes)
    timers = {"training": 0.0, "evaluation": 0.0}
    DeepAgent._step = timed(DeepAgent._step, timers, "training")
    play = envs.play_copies

    def play_copies(*args, **kwargs):
        if kwargs.get("learn", True):
            return play(*args, **kwargs)
        return timed(play, timers, "evaluation")(*args, **kwargs)

    envs.play_copies = play_copies
    spec = RunSpec.make(envs.EXPERIMENT, algorithm, settings, 0, seed)
    result = envs.run(settings, spec.seed_sequence())
    total = result["seconds"]
    collection = total - timers["training"] - timers["evaluation"]
    import cmarlcd

    return {
        "curve": [[budget * STEPS_PER_EPISODE, value] for budget, value, _ in result["curve"]],
        "seconds": {**timers, "collection": collection, "total": total},
        "versions": {"cmarl-cd": cmarlcd.__version__},
        "command": equivalent_command(frames, eval_every, episodes),
    }


def ours_settings(algorithm: str, frames: int, eval_every: int, episodes: int):
    """The settings of a cmarl-cd run (those of :func:`equivalent_command`)."""
    from cmarlcd.experiments import environment as envs
    from cmarlcd.learners.deep.config import DeepConfig

    return envs.EnvRun(
        ENV, ENV_KWARGS, DeepConfig(mixer=algorithm, **OURS), frames // STEPS_PER_EPISODE,
        episodes, frames // eval_every, "mean", "own-observations", SHARED["envs_per_side"],
    )  # fmt: skip


def timed(function: Callable, timers: dict, name: str) -> Callable:
    def wrapper(*args, **kwargs):
        started = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            timers[name] += time.perf_counter() - started

    return wrapper


def equivalent_command(frames: int, eval_every: int, episodes: int) -> str:
    """The ``cmarl-cd train`` command that stores the same runs as the cmarl-cd side."""
    kwargs = json.dumps(dict(ENV_KWARGS))
    sets = ",".join(f"{a}.{k}={v}" for a in ALGORITHMS for k, v in OURS.items())
    return (
        f"cmarl-cd train --env {ENV} --env-kwargs '{kwargs}' --algorithms vdn,qmix "
        f"--episodes {frames // STEPS_PER_EPISODE} --eval-episodes {episodes} "
        f"--curve-points {frames // eval_every} --reward mean --inputs own-observations "
        f"--envs {SHARED['envs_per_side']} --seed 0 --set {sets}"
    )


def compiled_settings(algorithm: str, frames: int, eval_every: int, episodes: int):
    """The settings of a cmarl-cd run on its compiled simple_spread (those of
    :func:`compiled_command`): the cmarl-cd side's, each agent on its own observation and
    the mean reward, on one copy of the game per seed."""
    from cmarlcd.experiments import games
    from cmarlcd.experiments.episodic import EpisodicRun
    from cmarlcd.games.spread import SimpleSpread
    from cmarlcd.learners.deep.config import DeepConfig

    options = games.SIMPLE_SPREAD.options(SimpleSpread(reward="mean"), "own-observations")
    return EpisodicRun(
        DeepConfig(mixer=algorithm, **OURS), (frames // STEPS_PER_EPISODE,), episodes,
        frames // eval_every, episodes, options,
    )  # fmt: skip


def compiled_run(algorithm: str, seed: int, frames: int, eval_every: int, episodes: int):
    """One cmarl-cd run on the compiled simple_spread, exactly as ``cmarl-cd train --game``
    makes run ``seed`` of root seed 0 (:func:`compiled_command`); one clock for all of it
    (the compiled loop does not split collection from training)."""
    import torch

    import cmarlcd
    from cmarlcd.experiments import games
    from cmarlcd.experiments.episodic import run_batch
    from cmarlcd.runs import RunSpec

    torch.set_num_threads(1)
    settings = compiled_settings(algorithm, frames, eval_every, episodes)
    family = games.SIMPLE_SPREAD
    spec = RunSpec.make(family.name, algorithm, settings, 0, seed)
    started = time.perf_counter()
    (result,) = run_batch(family.game, settings, [spec.seed_sequence()])
    total = time.perf_counter() - started
    unsplit = float("nan")
    return {
        "curve": [[point[0] * STEPS_PER_EPISODE, point[2]] for point in result["curve"]],
        "seconds": {
            "training": unsplit,
            "evaluation": unsplit,
            "collection": unsplit,
            "total": total,
        },
        "versions": {"cmarl-cd": cmarlcd.__version__},
        "command": compiled_command(frames, eval_every, episodes),
    }


def compiled_command(frames: int, eval_every: int, episodes: int) -> str:
    """The ``cmarl-cd train`` command that stores the runs of the compiled side."""
    sets = ",".join(f"{a}.{k}={v}" for a in ALGORITHMS for k, v in OURS.items())
    return (
        "cmarl-cd train --game simple_spread:reward=mean --inputs own-observations "
        f"--algorithms vdn,qmix --episodes {frames // STEPS_PER_EPISODE} "
        f"--eval-episodes {episodes} --curve-points {frames // eval_every} --seed-batch 1 "
        f"--seed 0 --set {sets}"
    )


JOBS: dict[str, Callable] = {
    "benchmarl": benchmarl_run,
    "cmarl-cd": ours_run,
    "cmarl-cd-compiled": compiled_run,
}


def check_task(episodes: int = 20) -> str:
    """Whether PettingZoo 1.25's ``pettingzoo.mpe`` simple_spread (BenchMARL's) and
    mpe2's give the same observations, rewards and states under the same seeds and
    random actions."""
    import numpy as np
    from mpe2 import simple_spread_v3 as ours
    from pettingzoo.mpe import simple_spread_v3 as theirs

    kwargs = dict(ENV_KWARGS)
    rng, steps = np.random.default_rng(0), 0
    for episode in range(episodes):
        a, b = ours.parallel_env(**kwargs), theirs.parallel_env(**kwargs)
        observations = [a.reset(seed=episode)[0], b.reset(seed=episode)[0]]
        while a.agents:
            assert_same(observations, a.state(), b.state())
            actions = {agent: int(rng.integers(5)) for agent in a.agents}
            first, second = a.step(actions), b.step(actions)
            observations = [first[0], second[0]]
            assert_same([first[1], second[1]], 0, 0)
            steps += 1
    return f"task check: mpe2 and pettingzoo.mpe simple_spread_v3 agree over {steps} steps"


def assert_same(pair: list[dict], state_a, state_b) -> None:
    import numpy as np

    first, second = pair
    if first.keys() != second.keys() or not np.array_equal(state_a, state_b):
        raise SystemExit("task check failed: the two simple_spread_v3 differ")
    for key in first:
        if not np.array_equal(first[key], second[key]):
            raise SystemExit(f"task check failed: {key} differs")


# ---------------------------------------------------------------------------- report

T_95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262}


def interval(values: list[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95 % t-interval over runs (0 for one run)."""
    n = len(values)
    mean = sum(values) / n
    if n < 2:
        return mean, 0.0
    sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))
    return mean, T_95.get(n - 1, 1.96) * sd / math.sqrt(n)


def summarise(out: Path, frames: int) -> dict:
    """Per side and algorithm: the curve's mean and interval at each frame count, and
    frames per second (collection, training, all)."""
    runs = [json.loads(p.read_text()) for p in stored_runs(out)]
    cells: dict[str, dict] = {}
    for side in SIDES:
        for algorithm in ALGORITHMS:
            mine = [r for r in runs if r["side"] == side and r["algorithm"] == algorithm]
            if mine:
                cells[f"{side}/{algorithm}"] = cell(mine)
    return {"frames": frames, "shared": SHARED, "cells": cells}


def cell(runs: list[dict]) -> dict:
    points = sorted({p[0] for r in runs for p in r["curve"]})
    curve = []
    for frame in points:
        values = [p[1] for r in runs for p in r["curve"] if p[0] == frame]
        curve.append([frame, *interval(values), len(values)])
    seconds = {k: sum(r["seconds"][k] for r in runs) for k in runs[0]["seconds"]}
    frames = sum(r["curve"][-1][0] for r in runs)
    return {
        "seeds": [r["seed"] for r in runs],
        "curve": curve,
        "final": curve[-1][1:3],
        "fps": {k: frames / max(v, 1e-9) for k, v in seconds.items() if k != "evaluation"},
        "seconds_per_run": {k: v / len(runs) for k, v in seconds.items()},
        "versions": runs[0]["versions"],
        **({"command": runs[0]["command"]} if "command" in runs[0] else {}),
    }


def table(summary: dict) -> str:
    lines = [
        f"{'side/algorithm':18} {'seeds':>5} {'final return/agent':>22} "
        f"{'collect fps':>11} {'train fps':>9} {'all fps':>8}"
    ]
    for name, c in summary["cells"].items():
        mean, half = c["final"]
        fps = c["fps"]
        lines.append(
            f"{name:18} {len(c['seeds']):>5} {mean:>12.2f} ± {half:<7.2f} "
            f"{fps['collection']:>11.0f} {fps['training']:>9.0f} {fps['total']:>8.0f}"
        )
    return "\n".join(lines)


def figure(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ALGORITHMS), figsize=(10, 3.6), sharey=True)
    for ax, algorithm in zip(axes, ALGORITHMS, strict=True):
        for side, colour in zip(SIDES, ("tab:gray", "tab:blue", "tab:green"), strict=True):
            c = summary["cells"].get(f"{side}/{algorithm}")
            if not c:
                continue
            x = [p[0] / 1e6 for p in c["curve"]]
            mean = [p[1] for p in c["curve"]]
            low = [p[1] - p[2] for p in c["curve"]]
            high = [p[1] + p[2] for p in c["curve"]]
            seeds = len(c["seeds"])
            label = f"{SIDE_NAMES[side]} ({seeds} seed{'s' if seeds > 1 else ''})"
            ax.plot(x, mean, color=colour, label=label)
            ax.fill_between(x, low, high, color=colour, alpha=0.2)
        ax.set_title(f"{algorithm.upper()} on simple_spread")
        ax.set_xlabel("frames (millions)")
        ax.grid(alpha=0.3)
        ax.legend()
    axes[0].set_ylabel("greedy return per agent")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
