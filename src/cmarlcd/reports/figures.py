"""Figures rendered from stored results (matplotlib, Agg backend, PNG files)."""

from __future__ import annotations

import os
import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cmarlcd.experiments.repeated import CellSummary

#: Characters of a legend line: a learner's label lists the settings changed from its
#: default, which can run to hundreds of characters (``--set``).
LEGEND_WIDTH = 60


def _wrapped(label: str) -> str:
    """A legend label on lines of at most :data:`LEGEND_WIDTH` characters."""
    return "\n".join(textwrap.wrap(label, LEGEND_WIDTH))


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
    return _save(fig, path)


def learning_curves(curves: dict[str, np.ndarray], path: Path) -> Path:
    """Success rate of the greedy policy vs learning episodes: mean over runs, 10-90 % band.

    ``curves[name]`` has shape (runs, points, 4): [episodes, success, return, steps].
    """
    plt = _pyplot()
    fig, (ax_success, ax_steps) = plt.subplots(1, 2, figsize=(11, 4))
    for name, data in curves.items():
        x = data[0, :, 0]
        label = _wrapped(f"{name} ({len(data)} runs)")
        for ax, column, scale in ((ax_success, 1, 100.0), (ax_steps, 3, 1.0)):
            values = scale * data[:, :, column]
            lo, hi = np.percentile(values, [10, 90], axis=0)
            (line,) = ax.plot(x, values.mean(axis=0), label=label)
            ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.2)
    ax_success.set_ylabel("success rate of the greedy policy (%)")
    ax_steps.set_ylabel("average steps per episode")
    for ax in (ax_success, ax_steps):
        ax.set_xlabel("learning episodes")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("DSN learning curves: mean over runs, band = 10th-90th percentile", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def scaling_curves(series: dict[str, np.ndarray], title: str, path: Path) -> Path:
    """Success and return per target against the state count (log axis), one line per
    learner. ``series[name]`` has rows [states, success, std of success over runs,
    return per target], one per size."""
    plt = _pyplot()
    fig, (ax_success, ax_return) = plt.subplots(1, 2, figsize=(11, 4))
    for name, rows in series.items():
        states, success, spread, per_target = rows.T
        (line,) = ax_success.plot(states, 100 * success, marker="o", label=_wrapped(name))
        ax_success.fill_between(
            states, 100 * (success - spread), 100 * (success + spread),
            color=line.get_color(), alpha=0.15,
        )  # fmt: skip
        ax_return.plot(states, per_target, marker="o", color=line.get_color(), label=_wrapped(name))
    ax_success.set_ylabel("episodes with every target captured (%)")
    ax_success.set_ylim(-3, 103)
    ax_return.set_ylabel("mean return per target")
    for ax in (ax_success, ax_return):
        ax.set_xscale("log")
        ax.set_xlabel("states of the network")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle(textwrap.fill(title, 110), fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def environment_curves(
    curves: dict[str, np.ndarray],
    baseline: str,
    title: str,
    path: Path,
    unit: str = "episodes",
) -> Path:
    """Greedy return against learning episodes, mean over runs with a 10-90 % band, one
    line per learner; ``baseline`` (the random policy) dashed. ``curves[name]`` has shape
    (runs, points, 3): [budget, return, steps], the budget in ``unit`` (learning
    episodes or environment steps)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, data in curves.items():
        x, values = data[0, :, 0], data[:, :, 1]
        style = {"linestyle": "--", "color": "grey"} if name == baseline else {}
        label = name if name == baseline and len(data) == 1 else f"{name} ({len(data)} runs)"
        label = _wrapped(label)  # a label with many settings
        (line,) = ax.plot(x, values.mean(axis=0), label=label, **style)
        lo, hi = np.percentile(values, [10, 90], axis=0)
        ax.fill_between(x, lo, hi, color=line.get_color(), alpha=0.15)
    ax.set_xlabel("learning episodes" if unit == "episodes" else "environment steps")
    ax.set_ylabel("return of the greedy policy (team)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(textwrap.fill(title, 80), fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def dsn_policy_grid(policy: np.ndarray, title: str, path: Path) -> Path:
    """Fig. 4: the greedy joint action in each of the 42 non-terminal DSN states.

    Each panel is the 2 × 3 grid with the targets (0 red, 1 blue; a captured target is
    absent) and a line from every focusing sensor to the cell it watches. A panel is
    titled in green when its joint action is optimal: exactly three sensors on each live
    target and no other sensor focusing.
    """
    from cmarlcd.games import sensor_network as dsn

    plt = _pyplot()
    fig, axes = plt.subplots(6, 7, figsize=(14, 10))
    for state, ax in enumerate(axes.flat):
        _draw_state(ax, state, policy[state], dsn)
    fig.suptitle(textwrap.fill(title, 150), fontsize=11)
    fig.legend(handles=_fig4_legend(), loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return _save(fig, path)


def _fig4_legend() -> list:
    """What the colours and lines of Fig. 4 mean."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    def dot(colour: str, label: str, size: float = 8) -> Line2D:
        return Line2D([], [], ls="", marker="o", color=colour, ms=size, label=label)

    def line(colour: str, label: str) -> Line2D:
        return Line2D([], [], color=colour, lw=1.5, label=label)

    return [
        dot("tab:red", "target 0"),
        dot("tab:blue", "target 1"),
        dot("0.3", "sensor", 3),
        line("tab:red", "sensor focusing target 0's cell"),
        line("tab:blue", "sensor focusing target 1's cell"),
        line("0.5", "sensor focusing an empty cell"),
        Patch(color="tab:green", label="panel title green: optimal (3 sensors per target)"),
        Patch(color="tab:red", label="panel title red: not optimal"),
    ]


def _draw_state(ax, state: int, joint: np.ndarray, dsn) -> None:
    targets = dsn.decode_state(state)
    colours = {targets[0]: "tab:red", targets[1]: "tab:blue"}
    for r in range(dsn.N_ROWS + 1):
        ax.plot([0, dsn.N_COLS], [-r, -r], color="0.7", lw=0.8)
    for c in range(dsn.N_COLS + 1):
        ax.plot([c, c], [0, -dsn.N_ROWS], color="0.7", lw=0.8)
    watchers = np.zeros(dsn.N_CELLS, dtype=int)
    for sensor, action in enumerate(joint):
        row, col = divmod(sensor, dsn.N_COLS + 1)
        ax.plot(col, -row, "o", color="0.3", ms=2.5)
        if action == 0:
            continue
        cell = int(dsn.SENSOR_CELLS[sensor, action - 1])
        watchers[cell] += 1
        cr, cc = divmod(cell, dsn.N_COLS)
        ax.plot([col, cc + 0.5], [-row, -cr - 0.5], color=colours.get(cell, "0.5"), lw=1.2)
    for k, cell in enumerate(targets):
        if cell >= 0:
            cr, cc = divmod(cell, dsn.N_COLS)
            ax.plot(cc + 0.5, -cr - 0.5, "o", color=colours[cell], ms=9)
            ax.text(
                cc + 0.5, -cr - 0.5, str(k), color="white", ha="center", va="center", fontsize=7
            )
    live = [cell for cell in targets if cell >= 0]
    optimal = all(watchers[c] == 3 for c in live) and watchers.sum() == 3 * len(live)
    ax.set_title(f"state {state}", fontsize=7, color="tab:green" if optimal else "tab:red")
    ax.set_xlim(-0.2, dsn.N_COLS + 0.2)
    ax.set_ylim(-dsn.N_ROWS - 0.2, 0.2)
    ax.set_aspect("equal")
    ax.axis("off")


def _save(fig, path: Path) -> Path:
    """Write ``fig`` as a PNG (creating folders) and release it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    _pyplot().close(fig)
    return path


def tournament_bars(
    cells: Sequence, metric: str, ylabel: str, title: str, path: Path, names: dict[str, str]
) -> Path:
    """Figs. 6-7: per algorithm, one bar per opponent (``metric`` of each
    :class:`cmarlcd.experiments.tournament_results.Cell`), error bars one spread over rounds.
    ``names`` maps the algorithms, in plotting order, to their display names."""
    plt = _pyplot()
    table = {(c.algorithm, c.opponent): c for c in cells}
    algorithms = [n for n in names if any(c.algorithm == n for c in cells)]
    width = 0.8 / max(len(algorithms), 1)
    fig, ax = plt.subplots(figsize=(max(7.0, 3.0 + 1.6 * len(algorithms)), 4.0))
    for k, opponent in enumerate(algorithms):
        heights, errors = [], []
        for algorithm in algorithms:
            cell = table.get((algorithm, opponent))
            heights.append(np.nan if cell is None else getattr(cell, metric))
            errors.append(np.nan if cell is None else getattr(cell, f"{metric}_std"))
        x = np.arange(len(algorithms)) + (k - (len(algorithms) - 1) / 2) * width
        ax.bar(x, heights, width, yerr=errors, capsize=3, label=f"vs {names[opponent]}")
    ax.set_xticks(np.arange(len(algorithms)), [names[a] for a in algorithms])
    ax.set_xlabel("algorithm")
    ax.set_ylabel(ylabel)
    if metric == "win_rate":
        ax.set_ylim(0, 1)
    ax.set_title(textwrap.fill(title, 70), fontsize=9)
    ax.legend(
        title="opponent",
        fontsize=8,
        title_fontsize=8,
        loc="center left",
        bbox_to_anchor=(1.0, 0.5),
        frameon=False,
    )
    fig.tight_layout()
    return _save(fig, path)


def comparison_heatmap(
    rates: np.ndarray, labels: Sequence[Sequence[str]], rows: Sequence[str],
    columns: Sequence[str], title: str, path: Path,
) -> Path:  # fmt: skip
    """Learners (rows) × games (columns): % of runs ending on an optimal joint action,
    coloured by it, each cell labelled (``labels``); NaN cells (not played) grey."""
    plt = _pyplot()
    from matplotlib.patheffects import withStroke

    halo = [withStroke(linewidth=2.5, foreground="white")]
    fig, ax = plt.subplots(figsize=(2.0 + 1.05 * len(columns), 1.4 + 0.5 * len(rows)))
    cmap = plt.get_cmap("RdYlGn").with_extremes(bad="#dddddd")
    image = ax.imshow(np.ma.masked_invalid(100 * rates), cmap=cmap, vmin=0, vmax=100, aspect="auto")
    fig.colorbar(image, ax=ax, shrink=0.8, label="% of runs optimal")
    ax.set_xticks(range(len(columns)), columns, rotation=35, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=9)
    for r, row in enumerate(labels):
        for c, text in enumerate(row):
            ax.text(c, r, text, ha="center", va="center", fontsize=7.5, path_effects=halo)
    ax.set_title(textwrap.fill(title, 95), fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def hit_rate_dial(
    points: dict[float, Sequence], names: dict[str, str], title: str, path: Path
) -> Path:
    """The battlefield's hit-rate dial: one panel per algorithm, its win rate against
    each opponent (one line each, error bars one spread over rounds) as the hit rate of
    both unit kinds runs over ``points`` (hit rate -> that tournament's
    :class:`cmarlcd.experiments.tournament_results.Cell` list)."""
    plt = _pyplot()
    rates = sorted(points)
    tables = {rate: {(c.algorithm, c.opponent): c for c in points[rate]} for rate in rates}
    algorithms = [n for n in names if any((n, n) in t for t in tables.values())]
    fig, axes = plt.subplots(
        1, len(algorithms), figsize=(3.2 * len(algorithms) + 1.6, 3.4), sharey=True, squeeze=False
    )
    for ax, algorithm in zip(axes[0], algorithms, strict=True):
        for opponent in algorithms:
            cells = [tables[rate].get((algorithm, opponent)) for rate in rates]
            y = [np.nan if c is None else 100 * c.win_rate for c in cells]
            err = [np.nan if c is None else 100 * c.win_rate_std for c in cells]
            ax.errorbar(rates, y, yerr=err, marker="o", capsize=3, label=f"vs {names[opponent]}")
        ax.axhline(50, color="grey", linewidth=0.6, linestyle=":")
        ax.set_title(names[algorithm], fontsize=9)
        ax.set_xlabel("hit rate of every unit")
        ax.set_xticks(rates)
    axes[0][0].set_ylabel("win rate (%)")
    axes[0][0].set_ylim(0, 100)
    axes[0][-1].legend(
        title="opponent", fontsize=8, title_fontsize=8, loc="center left",
        bbox_to_anchor=(1.0, 0.5), frameon=False,
    )  # fmt: skip
    fig.suptitle(textwrap.fill(title, 110), fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def gamma_dial(points: Sequence, names: dict[str, str], title: str, path: Path) -> Path:
    """The battlefield's γ dial: one panel per tabular learner (columns) and unit stats
    (rows: the defaults, then each hit rate of every unit), its margin against each
    opponent (win rate minus the opponent's, per round; error bars ± 2 standard errors)
    as the discount γ of the tabular learners runs over the dial, on a log axis that
    keeps γ = 0 (linear within 0.01 of it). ``points`` are
    :class:`cmarlcd.experiments.readings.DialMargin`."""
    from cmarlcd.experiments.tournament_claims import STANDARD_ERRORS

    plt = _pyplot()
    rates = sorted({p.hit_rate for p in points}, key=lambda r: (r is not None, r or 0.0))
    learners = [n for n in names if any(p.learner == n for p in points)]
    opponents = [n for n in names if any(p.opponent == n for p in points)]
    gammas = sorted({p.gamma for p in points})
    fig, axes = plt.subplots(
        len(rates), len(learners), figsize=(3.6 * len(learners) + 1.8, 2.9 * len(rates) + 0.6),
        sharex=True, sharey=True, squeeze=False,
    )  # fmt: skip
    for row, rate in zip(axes, rates, strict=True):
        for ax, learner in zip(row, learners, strict=True):
            for opponent in opponents:
                mine = sorted(
                    (p.gamma, p.margin)
                    for p in points
                    if (p.learner, p.opponent, p.hit_rate) == (learner, opponent, rate)
                )
                if not mine:
                    continue
                x = [gamma for gamma, _ in mine]
                y = [100 * m.value for _, m in mine]
                err = [100 * STANDARD_ERRORS * m.standard_error for _, m in mine]
                colour = f"C{opponents.index(opponent)}"  # one per opponent in every panel
                ax.errorbar(x, y, yerr=err, marker="o", capsize=3, color=colour)
            ax.axhline(0, color="grey", linewidth=0.6, linestyle=":")
            ax.set_xscale("symlog", linthresh=0.01, linscale=0.4)
            ax.set_xticks(gammas, [f"{g:g}" for g in gammas])
            ax.minorticks_off()
            units = "default unit stats" if rate is None else f"hit rate {rate:g}"
            ax.set_title(f"{names[learner]}, {units}", fontsize=9)
        row[0].set_ylabel("margin (points)")
    for ax in axes[-1]:
        ax.set_xlabel("γ of CMARL-CD and LA-OCA")
    from matplotlib.lines import Line2D

    keys = [
        Line2D([], [], color=f"C{i}", marker="o", label=f"vs {names[o]}")
        for i, o in enumerate(opponents)
    ]
    fig.suptitle(textwrap.fill(title, 110), fontsize=9)
    fig.tight_layout(rect=(0, 0, 0.86, 1))
    fig.legend(handles=keys, title="opponent", fontsize=8, title_fontsize=8,
               loc="center left", bbox_to_anchor=(0.86, 0.5), frameon=False)  # fmt: skip
    return _save(fig, path)


def phase_portrait(
    path: str | os.PathLike[str],
    temperature: float = 1.0,
    seed: int = 0,
    trajectories: int = 12,
) -> Path:
    """Theorem 1's phase portrait of the reduced system (12) for 2 agents and 2 optima
    (:func:`cmarlcd.theory.phase_portrait`); writes a PNG and returns its path.

    The state is ``(p_bar_11, p_bar_21)`` in ``[0, 1]^2``: the field as streamlines, the
    random starts' trajectories, the two optima (filled: stable by Theorem 1) and the
    other critical points (hollow): the mismatched corners and the centre all lie on the
    line of equilibria ``x + y = 1`` (dashed), where ``D_1 = D_2``.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    from cmarlcd.theory import phase_portrait as portrait_of

    data = portrait_of(temperature, seed, trajectories)
    fig = Figure(figsize=(6.4, 6.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    speed = np.hypot(data.u, data.v)
    shade = Normalize(vmin=-0.4 * speed.max(), vmax=speed.max())  # slowest still visible
    ax.streamplot(
        data.grid, data.grid, data.u, data.v, color=speed, cmap="Greys", norm=shade,
        density=1.2, linewidth=0.8,
    )  # fmt: skip
    ax.plot([0, 1], [1, 0], "--", color="tab:red", lw=1.2, label="equilibria: D₁ = D₂")
    for index, points in enumerate(data.trajectories):
        label = "trajectories of eq. (8)" if index == 0 else None
        ax.plot(points[:, 0], points[:, 1], color="tab:blue", lw=1.4, label=label)
        ax.plot(points[0, 0], points[0, 1], "o", color="tab:blue", ms=3)
    ax.plot([1, 0], [1, 0], "o", color="black", ms=10, label="optima (stable)", clip_on=False)
    ax.plot(
        [1, 0, 0.5], [0, 1, 0.5], "o", mfc="white", mec="tab:red", mew=1.5, ms=10,
        label="other critical points", clip_on=False,
    )  # fmt: skip
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_aspect("equal")
    ax.set_xlabel("p̄₁₁ (agent 1, action 1)")
    ax.set_ylabel("p̄₂₁ (agent 2, action 1)")
    ax.set_title(f"CMARL-CD Theorem 1: reduced system (eq. 12), n = m = 2, T = {temperature:g}")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    return out
