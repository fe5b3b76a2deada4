"""Benchmark: one task's run of the field's protocol, timed, and where the time goes.

A VDN run (``--learner``; ``--step`` its gradient step) of ``--steps`` environment steps
(2.05M, EPyMARL's budget) on a compiled task (``foraging:8x8-2p-2f-coop``), ``--seeds``
seeds stacked in one model as ``cmarl-cd field`` trains them, a greedy evaluation of
``--eval-episodes`` episodes every
``--eval-interval`` steps, at each preset of ``--presets`` (``paper``: the project's
settings; ``epymarl``: EPyMARL's, ``cmarl-cd field --preset epymarl``). After a short run
outside the clock (numba's compilation), the seconds are split by timing, in the run
itself:

* **gradient**: the model's learning steps (the fused or autograd TD step and Adam),
* **replay**: drawing the replay batches and handing them to the model,
* **weights**: copying the networks to the compiled loop after each step,
* **evaluation**: the greedy evaluations,
* **acting**: the rest (the compiled loop playing, choosing and storing; target copies).

Usage: python benchmarks/bench_field_training.py [--learner vdn] [--step auto]
           [--task foraging:8x8-2p-2f-coop]
           [--steps 2.05M] [--seeds 5] [--presets paper,epymarl] [--eval-interval 50k]
           [--eval-episodes 100] [--share] [--inputs observations] [--layers 1]
           [--hypernet-layers 1] [--json]

``--layers`` and ``--hypernet-layers`` (QMIX) give EPyMARL's model class (2 and 2).
(torch: pip install -e ".[deep]")
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import replace
from datetime import date

import numpy as np

from cmarlcd import registry
from cmarlcd.cli.field import evaluation_points, with_preset
from cmarlcd.cli.options import parse_count
from cmarlcd.experiments import games
from cmarlcd.experiments.episodic import EpisodicRun, Recorder, run_batch

PARTS = ("gradient", "replay", "weights", "evaluation")


@contextmanager
def timed(seconds: dict[str, float]):
    """Inside the block, the calls of each part's function add their seconds to
    ``seconds[part]``."""
    from cmarlcd.learners.deep.value_decomposition import ValueDecomposition
    from cmarlcd.training.deep_side import DeepGroup

    targets = {
        "gradient": (ValueDecomposition, "learn"),
        "replay": (DeepGroup, "sample"),
        "weights": (DeepGroup, "_copy_weights"),
        "evaluation": (Recorder, "_evaluate"),
    }
    originals = {part: getattr(owner, name) for part, (owner, name) in targets.items()}

    def clocked(part, function):
        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                seconds[part] += time.perf_counter() - start

        return call

    for part, (owner, name) in targets.items():
        setattr(owner, name, clocked(part, originals[part]))
    try:
        yield
    finally:
        for part, (owner, name) in targets.items():
            setattr(owner, name, originals[part])


def one_run(
    name: str, step: str, task: str, preset: str, steps: int, seeds: int, interval: int,
    episodes: int, share: bool = False, inputs: str = "observations", layers: int = 1,
    hypernet_layers: int = 1,
):  # fmt: skip
    """(wall seconds, seconds per part, the learner's settings, the runs' metrics)."""
    family, rules = games.parse_game(task)
    base = registry.require_learner(name)
    (learner,) = with_preset((base,), preset, rules.spec().max_steps)
    learner = replace(learner, step=step, share=share, hidden_layers=layers)
    if hypernet_layers != 1:
        learner = replace(learner, hypernet_layers=hypernet_layers)
    settings = EpisodicRun(
        learner, (steps,), episodes, evaluation_points(steps, interval), episodes,
        family.options(rules, inputs), unit="steps",
    )  # fmt: skip
    sequences = [np.random.SeedSequence(k) for k in range(seeds)]
    seconds: dict[str, float] = defaultdict(float)
    with timed(seconds):
        start = time.perf_counter()
        metrics = run_batch(family.game, settings, sequences)
        wall = time.perf_counter() - start
    return wall, dict(seconds), learner, metrics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--learner", default="vdn", help="vdn, qmix, deep-iql, hysteretic-dqn")
    parser.add_argument("--step", default="auto", help="auto, fused or autograd")
    parser.add_argument("--task", default="foraging:8x8-2p-2f-coop")
    parser.add_argument("--steps", default="2.05M")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--presets", default="paper,epymarl")
    parser.add_argument("--eval-interval", default="50k")
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--share", action="store_true", help="one network for the agents")
    parser.add_argument("--inputs", default="observations", help="or own-observations")
    parser.add_argument("--layers", type=int, default=1, help="hidden layers of each network")
    parser.add_argument("--hypernet-layers", type=int, default=1, help="QMIX's: 1 or 2")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)
    steps = parse_count(args.steps, "--steps")
    interval = parse_count(args.eval_interval, "--eval-interval")
    rows = []
    for preset in args.presets.split(","):
        what = (args.learner, args.step, args.task, preset)
        form = (args.share, args.inputs, args.layers, args.hypernet_layers)
        one_run(*what, 2_000, 1, 1_000, 2, *form)  # compiled outside the clock
        wall, seconds, learner, metrics = one_run(
            *what, steps, args.seeds, interval, args.eval_episodes, *form
        )
        acting = wall - sum(seconds.get(part, 0.0) for part in PARTS)
        last = [run["curve"][-1][2] for run in metrics]
        rows.append(
            {
                "preset": preset,
                "step": learner.step
                if learner.step != "auto"
                else ("fused" if learner.auto_fuses else "autograd"),
                "minutes": round(wall / 60, 2),
                "steps_per_second": round(args.seeds * steps / wall),
                "seconds": {
                    "acting": round(acting, 1),
                    **{part: round(seconds.get(part, 0.0), 1) for part in PARTS},
                },
                "final_return_per_seed": [round(x, 3) for x in last],
            }
        )
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    head = {
        "date": str(date.today()),
        "machine": machine,
        "learner": args.learner,
        "task": args.task,
        "steps": steps,
        "seeds": args.seeds,
        "eval_interval": interval,
        "eval_episodes": args.eval_episodes,
        "share": args.share,
        "layers": args.layers,
        "hypernet_layers": args.hypernet_layers,
    }
    if args.json:
        print(json.dumps({**head, "runs": rows}, indent=2))
        return
    print(f"{machine}, Python {platform.python_version()}, {date.today()}, one thread")
    name = registry.display_name(args.learner)
    model = f", {args.layers} hidden layers" + (", shared" if args.share else "")
    print(f"{name}{model} on {args.task}: {steps:,} steps x {args.seeds} seeds stacked, "
          f"an evaluation of {args.eval_episodes} episodes every {interval:,} steps")  # fmt: skip
    for row in rows:
        parts = ", ".join(f"{k} {v:.1f} s" for k, v in row["seconds"].items())
        print(f"  {row['preset']:8s} ({row['step']} step): {row['minutes']:.2f} min, "
              f"{row['steps_per_second']:,} steps/s in all; {parts}")  # fmt: skip


if __name__ == "__main__":
    main()
