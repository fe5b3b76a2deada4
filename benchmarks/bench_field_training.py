"""Benchmark: one task's run of the field's protocol, timed, and where the time goes.

A VDN run (``--learner``; ``--step`` its gradient step, or several, comma-separated, each
run in turn, the first the baseline the others' ratios are to) of ``--steps`` environment steps
(2.05M, EPyMARL's budget) on a compiled task (``foraging:8x8-2p-2f-coop``), ``--seeds``
seeds stacked in one model as ``cmarl-cd field`` trains them, a greedy evaluation of
``--eval-episodes`` episodes every
``--eval-interval`` steps, at each preset of ``--presets`` (``paper``: the project's
settings; ``epymarl``: EPyMARL's, ``cmarl-cd field --preset epymarl``), or deep CMARL-CD at
a named design (``--learner deep-cmarl-cd --design NAME``, the field's discount 0.99, as
``cmarl-cd field --set deep-cmarl-cd.design=NAME,deep-cmarl-cd.gamma=0.99``; no preset).
After a short run
outside the clock (numba's compilation), the seconds are split by timing, in the run
itself:

* **gradient**: the model's learning steps (the fused or autograd TD step and Adam),
* **replay**: drawing the replay batches and handing them to the model,
* **weights**: copying the networks to the compiled loop after each step,
* **evaluation**: the greedy evaluations,
* **acting**: the rest (the compiled loop playing, choosing and storing; target copies).

Usage: python benchmarks/bench_field_training.py [--learner vdn] [--step auto[,fused,...]]
           [--task foraging:8x8-2p-2f-coop]
           [--steps 2.05M] [--seeds 5] [--presets paper,epymarl] [--eval-interval 50k]
           [--eval-episodes 100] [--share] [--inputs observations] [--layers 1]
           [--hypernet-layers 1] [--design NAME] [--json]

``--layers`` and ``--hypernet-layers`` (QMIX) give EPyMARL's model class (2 and 2);
``--share`` and ``--layers``, where given, override a design's own.
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
    from cmarlcd.learners.deep.degree_model import DegreeModel
    from cmarlcd.learners.deep.value_decomposition import ValueDecomposition
    from cmarlcd.training.deep_side import DeepGroup

    targets = [
        ("gradient", ValueDecomposition, "learn"),
        ("gradient", DegreeModel, "learn"),
        ("replay", DeepGroup, "sample"),
        ("weights", DeepGroup, "_copy_weights"),
        ("evaluation", Recorder, "_evaluate"),
    ]
    originals = [getattr(owner, name) for _, owner, name in targets]

    def clocked(part, function):
        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                seconds[part] += time.perf_counter() - start

        return call

    for (part, owner, name), original in zip(targets, originals, strict=True):
        setattr(owner, name, clocked(part, original))
    try:
        yield
    finally:
        for (_, owner, name), original in zip(targets, originals, strict=True):
            setattr(owner, name, original)


def learner_for(name: str, preset: str, design: str | None, max_steps: int):
    """The learner's settings: at the preset, or deep CMARL-CD's named design with the
    field's discount."""
    if design is not None:
        from cmarlcd.learners.deep.designs import DESIGNS

        return replace(DESIGNS[design], gamma=0.99)
    (learner,) = with_preset((registry.require_learner(name),), preset, max_steps)
    return learner


def one_run(
    name: str, step: str, task: str, preset: str, steps: int, seeds: int, interval: int,
    episodes: int, share: bool | None = None, inputs: str = "observations",
    layers: int | None = None, hypernet_layers: int = 1, design: str | None = None,
):  # fmt: skip
    """(wall seconds, seconds per part, the learner's settings, the runs' metrics)."""
    family, rules = games.parse_game(task)
    learner = replace(learner_for(name, preset, design, rules.spec().max_steps), step=step)
    if share is not None:
        learner = replace(learner, share=share)
    if layers is not None:
        learner = replace(learner, hidden_layers=layers)
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
    parser.add_argument(
        "--share", action="store_true", default=None, help="one network for the agents"
    )
    parser.add_argument("--inputs", default="observations", help="or own-observations")
    parser.add_argument("--layers", type=int, help="hidden layers of each network (1)")
    parser.add_argument("--hypernet-layers", type=int, default=1, help="QMIX's: 1 or 2")
    parser.add_argument("--design", help="deep CMARL-CD's design (--learner deep-cmarl-cd)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    if args.design is not None:
        from cmarlcd.learners.deep.designs import DESIGNS

        if args.learner != "deep-cmarl-cd" or args.design not in DESIGNS:
            parser.error(f"--design takes --learner deep-cmarl-cd and one of {', '.join(DESIGNS)}")
        args.presets = "design"
    if args.layers is None and args.design is None:
        args.layers = 1
    import torch

    torch.set_num_threads(1)
    steps = parse_count(args.steps, "--steps")
    interval = parse_count(args.eval_interval, "--eval-interval")
    rows = []
    runs = [(p, step) for p in args.presets.split(",") for step in args.step.split(",")]
    for preset, step in runs:
        what = (args.learner, step, args.task, preset)
        form = (args.share, args.inputs, args.layers, args.hypernet_layers, args.design)
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
    for row in rows:  # the first run is the baseline, measured in the same invocation
        row["speed_vs_first"] = round(row["steps_per_second"] / rows[0]["steps_per_second"], 2)
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
        "design": args.design,
    }
    if args.json:
        print(json.dumps({**head, "runs": rows}, indent=2))
        return
    print(f"{machine}, Python {platform.python_version()}, {date.today()}, one thread")
    name = registry.display_name(args.learner)
    if args.design is not None:
        config = learner_for(args.learner, "", args.design, 0)
        layers, share = args.layers or config.hidden_layers, args.share or config.share
        name += f" ({args.design})"
    else:
        layers, share = args.layers, args.share
    model = f", {layers} hidden layers" + (", shared" if share else "")
    print(f"{name}{model} on {args.task}: {steps:,} steps x {args.seeds} seeds stacked, "
          f"an evaluation of {args.eval_episodes} episodes every {interval:,} steps")  # fmt: skip
    for row in rows:
        parts = ", ".join(f"{k} {v:.1f} s" for k, v in row["seconds"].items())
        print(f"  {row['preset']:8s} ({row['step']} step): {row['minutes']:.2f} min, "
              f"{row['steps_per_second']:,} steps/s in all ({row['speed_vs_first']:.2f}x the "
              f"first); {parts}")  # fmt: skip


if __name__ == "__main__":
    main()
