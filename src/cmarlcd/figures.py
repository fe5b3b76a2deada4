"""Figures rendered from stored results (matplotlib, Agg backend, PNG files)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cmarlcd.experiments.repeated import CellSummary


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def repeated_heatmap(cells: Sequence[CellSummary], title: str, path: Path) -> Path:
    """Success rate (ours, the paper's in brackets) and median games, one panel each."""
    plt = _pyplot()
    from matplotlib.patheffects import withStroke

    halo = [withStroke(linewidth=2.5, foreground="white")]
    agents = sorted({c.agents for c in cells})
    actions = sorted({c.actions for c in cells})
    success = np.full((len(actions), len(agents)), np.nan)
    games = np.full_like(success, np.nan)
    labels: dict[tuple[int, int], tuple[str, str]] = {}
    for c in cells:
        r, k = actions.index(c.actions), agents.index(c.agents)
        success[r, k] = 100 * c.success_rate
        games[r, k] = np.log10(c.median_games) if c.median_games else np.nan
        paper = "" if c.paper_success_rate is None else f"\n({100 * c.paper_success_rate:.0f})"
        med = "—" if c.median_games is None else f"{c.median_games:,.0f}"
        labels[(r, k)] = (f"{100 * c.success_rate:.0f}{paper}", med)
    fig, axes = plt.subplots(1, 2, figsize=(3.2 + 1.6 * len(agents), 1.2 + 1.1 * len(actions)))
    panels = [
        (success, "success rate % (paper's in brackets)", "RdYlGn", (80, 100), 0),
        (games, "median games to convergence (colour: log10)", "viridis", (None, None), 1),
    ]
    for ax, (data, name, cmap, (lo, hi), which) in zip(axes, panels, strict=True):
        image = ax.imshow(data, cmap=cmap, vmin=lo, vmax=hi, aspect="auto")
        fig.colorbar(image, ax=ax, shrink=0.8)
        ax.set_xticks(range(len(agents)), [f"{n}" for n in agents])
        ax.set_yticks(range(len(actions)), [f"{m}" for m in actions])
        ax.set_xlabel("agents n")
        ax.set_ylabel("actions m")
        ax.set_title(name, fontsize=9)
        for (r, k), text in labels.items():
            ax.text(k, r, text[which], ha="center", va="center", fontsize=8, path_effects=halo)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
