"""Diagnostic: what deep CMARL-CD's keyed memory holds while it learns a field task, and
whether its degree network has fitted it.

Where the selection run finds a design learning nothing, this locates the loss: at each
checkpoint of one seed's learning it prints how many states the memory keeps, how many
of them hold a record above 0 (an episode that earned a reward passed through them), the
share of kept states whose greedy joint action by the network is the memory's (each agent
alike; about 1/6 per agent is chance on LBF), the mean gap between a kept state's largest
and smallest target degree (1 after the table's reset, smaller once ties move them), and
the returns folded so far (their standard deviation and range: what ``unseen_tolerance``
scales).

    python benchmarks/deep_cmarlcd_memory.py foraging:8x8-2p-2f-coop --steps 100k
    python benchmarks/deep_cmarlcd_memory.py foraging:8x8-2p-2f-coop --steps 100k \\
        --set unseen_tolerance=0.1,unseen_spread=range

Needs the ``[deep]`` extra. The discount is the field's (0.99) unless ``--set`` names one.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace

import numpy as np


def arguments(doc: str, example: str) -> argparse.ArgumentParser:
    """The deep CMARL-CD diagnostics' common arguments: a field task, the steps of
    learning, the seed and ``--set``."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    p.add_argument("task", help=f"a field task, e.g. {example}")
    p.add_argument("--steps", default="100k", help="environment steps of learning")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", default="", help="deep CMARL-CD settings, key=value,...")
    return p


def task_and_settings(args: argparse.Namespace, base) -> tuple:
    """The task's game spec, ``base`` at the field's discount (0.99) with ``--set``
    applied, and the steps; a bad value raises :class:`cmarlcd.errors.ConfigError`."""
    from cmarlcd.cli.options import apply_settings, parse_count
    from cmarlcd.experiments import games

    steps = parse_count(args.steps, "steps")
    _, rules = games.parse_game(args.task)
    settings = ",".join(f"deep-cmarl-cd.{kv.strip()}" for kv in args.set.split(",") if kv)
    (config,) = apply_settings(settings, (replace(base, gamma=0.99),))
    return rules.spec(), config, steps


def main(argv: Sequence[str] | None = None) -> int:
    p = arguments(__doc__, "foraging:8x8-2p-2f-coop")
    p.add_argument("--checkpoints", type=int, default=5, help="reports along the way")
    args = p.parse_args(argv)
    from cmarlcd.errors import ConfigError
    from cmarlcd.learners.deep.coordination import DeepCMARLCDConfig

    try:
        spec, config, steps = task_and_settings(args, DeepCMARLCDConfig())
    except ConfigError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    if args.checkpoints < 1 or steps < args.checkpoints:
        print("error: --checkpoints: must be between 1 and --steps", file=sys.stderr)
        return 2
    report(spec, config, steps, args.checkpoints, args.seed)
    return 0


def report(spec, config, steps: int, checkpoints: int, seed: int) -> None:
    import torch

    from cmarlcd.training.deep import DeepBatch

    batch = DeepBatch(spec, config, [np.random.SeedSequence(seed)], steps, unit="steps")
    print("steps | kept | records > 0 | network's greedy = memory's | target gap | "
          "returns' sd | range")  # fmt: skip

    def at(k: int, done: int, policy) -> None:
        view = batch.group.views[0]
        memory = view.data.replay.memory
        kept = memory.order[: int(memory.size[0])]
        moments = memory.returns[0]
        sd = np.sqrt(moments[2] / moments[0]) if moments[0] > 1 else 0.0
        line = f"{done:,} | {len(kept):,} | "
        if len(kept):
            targets = memory.target[kept]
            inputs = torch.from_numpy(np.ascontiguousarray(memory.state[kept]))
            with torch.no_grad():
                degrees = view.model.agents(inputs[None])[0].numpy()
            legal = np.arange(targets.shape[-1]) < spec.action_counts[:, None]
            network = np.where(legal, degrees, -np.inf).argmax(-1)
            memory_says = np.where(legal, targets, -np.inf).argmax(-1)
            gap = np.where(legal, targets, -np.inf).max(-1) - np.where(legal, targets, np.inf).min(
                -1
            )
            line += (f"{np.mean(memory.record[kept] > 0):.3f} | "
                     f"{np.mean(np.all(network == memory_says, axis=-1)):.3f} | "
                     f"{gap.mean():.2f} | ")  # fmt: skip
        else:
            line += "– | – | – | "
        print(line + f"{sd:.4f} | {moments[4] - moments[3]:.3f}", flush=True)

    batch.train([steps * k // checkpoints for k in range(checkpoints + 1)], at)


if __name__ == "__main__":
    sys.exit(main())
