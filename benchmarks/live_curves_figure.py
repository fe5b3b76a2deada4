"""The live curves of a ``--log-dir`` folder drawn from its event files, read with
TensorBoard's own reader (what ``tensorboard --logdir DIR`` shows, as one picture for the
docs): each run's greedy return, loss, ε and rate against its learning, one line a run,
coloured by learner.

Usage: python benchmarks/live_curves_figure.py LOG_DIR OUT.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from tensorboard.backend.event_processing.event_accumulator import (
    EventAccumulator,
)

PANELS = (
    ("eval/return", "greedy return"),
    ("train/loss", "TD loss"),
    ("train/epsilon", "ε"),
    ("rate/steps_per_second", "environment steps a second"),
)


def main(folder: Path, out: Path) -> None:
    runs = sorted(p for p in folder.iterdir() if p.is_dir())
    learners = sorted({run.name.split("-seed")[0] for run in runs})
    colours = {name: f"C{k}" for k, name in enumerate(learners)}
    figure, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharex=True)
    for run in runs:
        reader = EventAccumulator(str(run))
        reader.Reload()
        tags = set(reader.Tags()["scalars"])
        learner = run.name.split("-seed")[0]
        for axis, (tag, _) in zip(axes.flat, PANELS, strict=True):
            if tag in tags:
                points = reader.Scalars(tag)
                axis.plot([p.step for p in points], [p.value for p in points],
                          color=colours[learner], alpha=0.7, lw=1.2)  # fmt: skip
    axes[0][1].set_yscale("log")  # a loss that diverges spans many decades
    for axis, (_, label) in zip(axes.flat, PANELS, strict=True):
        axis.set_title(label, fontsize=10)
        axis.grid(alpha=0.3)
    for axis in axes[1]:
        axis.set_xlabel("environment steps")
    handles = [plt.Line2D([], [], color=colours[n], label=n) for n in learners]
    figure.legend(handles=handles, loc="lower center", ncol=len(learners), frameon=False)
    figure.suptitle(f"{folder.name}: {len(runs)} runs, read back from their event files")
    figure.tight_layout(rect=(0, 0.05, 1, 0.97))
    figure.savefig(out, dpi=110)
    print(f"{out}: {len(runs)} runs")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(Path(sys.argv[1]), Path(sys.argv[2]))
