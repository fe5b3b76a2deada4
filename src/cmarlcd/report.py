"""Reports rendered from stored runs: paper-style tables, their figures, their JSON.

Each ``*_report`` function takes the stored records of one group of runs (one table's
worth), draws its figures into a folder, prints its tables to a rich console (or
nothing, for ``--json``; or records them in a :class:`~cmarlcd.document.Recorder`, for a
Markdown or HTML report) and returns the JSON document of the group, with its title, its
settings and the package versions its runs were computed by (a warning is shown when
they differ). Figure files are named by
what they show: a readable stem and a digest of the group's settings, so groups with
other settings never overwrite each other; the printed line after each figure says
which settings it shows.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table
from rich.text import Text

from cmarlcd.document import Recorder, version_warning
from cmarlcd.experiments import episodic
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.experiments.episodic import EpisodicGame, Row
from cmarlcd.experiments.repeated import CellSummary
from cmarlcd.store import RunRecord

#: Success rates below this are shown in red (the acceptance bar for Tables 1-2).
SUCCESS_BAR = 0.96


def percent(rate: float | None) -> str:
    """``0.98`` -> ``"98"``; keeps one decimal when it matters (``"97.5"``)."""
    if rate is None:
        return "—"
    value = 100.0 * rate
    return f"{value:.0f}" if abs(value - round(value)) < 1e-9 else f"{value:.1f}"


Output = Console | Recorder


def show(console: Output, table: Table) -> None:
    """Print ``table`` with its title and caption as lines of their own: a narrow table
    would wrap them to its width."""
    if isinstance(console, Recorder):
        console.table(table)
        return
    title, caption = table.title, table.caption
    table.title = table.caption = None
    if title:
        console.print(Text(str(title), style="bold"), soft_wrap=True)
    console.print(table)
    if caption:
        console.print(Text(str(caption), style="dim"), soft_wrap=True)


def say(console: Output, text: str) -> None:
    """One line of plain text (paths stay whole: no wrapping)."""
    if isinstance(console, Recorder):
        console.text(text)
        return
    console.print(Text(text), soft_wrap=True)


def figure_line(console: Output, path: Path, what: str) -> None:
    """Where a figure was drawn and what it shows."""
    if isinstance(console, Recorder):
        console.figure(path, what)
        return
    say(console, f"figure: {path} ({what})")


def versions(records: Sequence[RunRecord], console: Output | None) -> dict[str, int]:
    """Runs per package version; warns when a group mixes versions."""
    counts = Counter(rec.version for rec in records)
    warning = version_warning(counts)
    if warning is not None and console is not None:
        if isinstance(console, Recorder):
            console.text(warning, warning=True)
        else:
            console.print(Text(warning, style="bold yellow"), soft_wrap=True)
    return dict(counts)


def figure_name(stem: str, settings: Any) -> str:
    """``stem`` plus a short digest of ``settings`` (anything JSON can write)."""
    text = json.dumps(settings, sort_keys=True, default=str)
    return f"{stem}-{hashlib.sha256(text.encode()).hexdigest()[:8]}.png"


def runs_text(counts: Sequence[int], unit: str) -> str:
    """``"20 runs per cell"``, or a range when cells differ."""
    low, high = min(counts), max(counts)
    return f"{low} runs per {unit}" if low == high else f"{low}-{high} runs per {unit}"


# ------------------------------------------------------------------ Tables 1 and 2


def _grid_table(
    cells: Sequence[CellSummary],
    title: str,
    render: Callable[[CellSummary], str],
    caption: str | None = None,
) -> Table:
    """The paper's layout: one row per action count m, one column per agent count n."""
    agents = sorted({c.agents for c in cells})
    actions = sorted({c.actions for c in cells})
    by_cell = {(c.agents, c.actions): c for c in cells}
    table = Table(title=title, caption=caption)
    table.add_column("", no_wrap=True)
    for n in agents:
        table.add_column(f"n={n}", justify="right", no_wrap=True)
    for m in actions:
        row = [f"m={m}"]
        for n in agents:
            cell = by_cell.get((n, m))
            row.append("" if cell is None else render(cell))
        table.add_row(*row)
    return table


def _success(cell: CellSummary) -> str:
    style = "green" if cell.success_rate >= SUCCESS_BAR else "red"
    ours = f"[{style}]{percent(cell.success_rate)}[/]"
    if cell.paper_success_rate is None:
        return ours
    return f"{ours} [dim]({percent(cell.paper_success_rate)})[/]"


def _median_games(cell: CellSummary) -> str:
    return "—" if cell.median_games is None else f"{cell.median_games:,.0f}"


def success_table(cells: Sequence[CellSummary], title: str) -> Table:
    """Success rate per cell, beside the paper's when the settings are the paper's."""
    paper = any(c.paper_success_rate is not None for c in cells)
    what = "ours (the paper's)" if paper else "ours (settings differ from the paper's)"
    caption = f"success % per cell: {what}; rows: actions m, columns: agents n"
    return _grid_table(cells, title, _success, caption)


def games_table(cells: Sequence[CellSummary], title: str) -> Table:
    """Median games to convergence per cell (the paper does not report it)."""
    return _grid_table(cells, title, _median_games)


def repeated_report(
    records: Sequence[RunRecord], figures: Path, console: Output | None
) -> dict[str, Any]:
    """Table 1 or 2 and its heatmap from the records of one group of runs."""
    from cmarlcd import figures as figs

    cells = rep.summarize(records)
    title = rep.table_title(records)
    case, seed = records[0].config["case"], records[0].key.root_seed
    settings = rep.group_key(records[0].config, seed)
    name = figure_name(f"repeated-case{case}-seed{seed}", settings)
    path = figs.repeated_heatmap(cells, title, figures / name)
    settings = rep.settings_text(records)
    if console is not None:
        show(console, success_table(cells, title))
        show(console, games_table(cells, f"Median games to convergence ({settings})"))
        figure_line(console, path, settings)
    return {
        "experiment": rep.EXPERIMENT,
        "title": f"Table {case}: random cooperative repeated games, case {case}",
        "settings": settings,
        "versions": versions(records, console),
        "case": case,
        "seed": seed,
        "figure": str(path),
        "cells": [c.to_dict() for c in cells],
    }


# ----------------------------------------------------------------- Tables 3 to 7

#: (table number, title, metrics shown as "a | b", number format)
DSN_TABLES = (
    (3, "Success rate for the DSN task (%)", ("success_rate",), "pct"),
    (4, "Average cumulative reward (mean | std over runs)", ("mean_return", "std_return"), ".2f"),
    (5, "Average steps (mean | std over runs)", ("mean_steps", "std_steps"), ".2f"),
    (6, "Minimum over runs of the average cumulative reward", ("min_return",), ".2f"),
    (7, "Maximum over runs of the average steps", ("max_steps",), ".2f"),
)


def _format(value: float | None, fmt: str) -> str:
    if value is None:
        return "—"
    return f"{100 * value:.2f}" if fmt == "pct" else format(value, fmt)


def dsn_tables(rows: Sequence[Row], protocol: str = "") -> list[Table]:
    """Tables 3-7 in the paper's layout: algorithms by row, L by column; ours, and the
    paper's in brackets for the rows run with the paper's settings."""
    budgets = sorted({r.episodes for r in rows})
    labels = list(dict.fromkeys(r.label for r in rows))
    by_cell = {(r.label, r.episodes): r for r in rows}
    paper = any(v is not None for r in rows for v in r.paper.values())
    suffix = f" ({protocol})" if protocol else ""
    tables = []
    for number, title, metrics, fmt in DSN_TABLES:
        table = Table(title=f"Table {number}. {title}{suffix}", show_lines=True)
        table.add_column("ours\n(paper)" if paper else "ours", no_wrap=True)
        for budget in budgets:
            table.add_column(f"L = {budget:,}", justify="right", no_wrap=True)
        for label in labels:
            cells = [label]
            for budget in budgets:
                row = by_cell.get((label, budget))
                if row is None:
                    cells.append("")
                    continue
                ours = " | ".join(_format(getattr(row, m), fmt) for m in metrics)
                if any(row.paper[m] is not None for m in metrics):
                    ours += (
                        "\n[dim]("
                        + " | ".join(_format(row.paper[m], fmt) for m in metrics)
                        + ")[/]"
                    )
                cells.append(ours)
            table.add_row(*cells)
        tables.append(table)
    return tables


TRAIN_ONCE_NOTE = (
    "CMARL-CD and LA-OCA do not depend on L: each run trains once to the largest L and is "
    "evaluated at every L on the way. VDN and QMIX anneal ε over L (eq. 18), so each L is "
    "a run of its own."
)


def protocol_text(records: Sequence[RunRecord], rows: Sequence[Row]) -> str:
    """What the tables of a group show: seed, runs per cell, evaluation episodes."""
    cfg = records[0].config
    runs = runs_text([r.runs for r in rows], "cell")
    return f"seed {records[0].key.root_seed}, {runs}, {cfg['eval_episodes']:,} evaluation episodes"


def dsn_report(
    game: EpisodicGame, records: Sequence[RunRecord], figures: Path, console: Output | None
) -> dict[str, Any]:
    """Tables 3-7, the learning curves and Fig. 4 of one group of DSN runs."""
    from cmarlcd import figures as figs

    rows = episodic.summarize(game, records)
    seed = records[0].key.root_seed
    protocol = protocol_text(records, rows)
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    curves_name = figure_name(f"dsn-learning-curves-seed{seed}", group)
    curves = figs.learning_curves(episodic.learning_curves(records), figures / curves_name)
    paths = {"learning_curves": str(curves)}
    shown = {"learning_curves": f"learning curves, {protocol}"}
    for rec in records:
        if rec.key.run_index == 0:
            label = episodic.row_label(rec.key.algorithm, rec.config["learner"])
            largest = max(rec.config["checkpoints"])
            what = f"{label}, L = {largest:,}, seed {seed}, run 0"
            title = f"Fig. 4 — greedy joint action of {what} in each of the 42 states"
            stem = f"dsn-fig4-{rec.key.algorithm}-L{largest}-seed{seed}"
            path = figs.dsn_policy_grid(
                np.array(rec.metrics["policy"]), title, figures / figure_name(stem, rec.key.config)
            )
            key = f"fig4_{rec.key.algorithm}_L{largest}"
            paths[key], shown[key] = str(path), f"Fig. 4, {what}"
    if console is not None:
        say(console, TRAIN_ONCE_NOTE)
        for table in dsn_tables(rows, protocol):
            show(console, table)
        for key, path in paths.items():
            figure_line(console, Path(path), shown[key])
    return {
        "experiment": game.experiment,
        "title": "Tables 3-7 and Fig. 4: the distributed sensor network task",
        "settings": protocol,
        "versions": versions(records, console),
        "seed": seed,
        "note": TRAIN_ONCE_NOTE,
        "rows": [r.to_dict() for r in rows],
        "figures": paths,
    }


# ------------------------------------------------------------------- Theorem 1


def theory_report(doc: dict[str, Any], console: Output) -> None:
    """Where the ODE starts went, and the Jacobian's eigenvalues against eq. (13)."""
    n, m, t = doc["n_agents"], doc["n_optima"], doc["temperature"]
    if not isinstance(console, Recorder):
        console.print(f"[bold]Theorem 1[/]: {n} agents, {m} optimal joint actions, T = {t:g}")
    reached = ", ".join(f"optimum {j}: {k}" for j, k in enumerate(doc["converged_to"]))
    say(
        console,
        f"ODE (8) from {doc['starts']} random interior starts -> {reached}; "
        f"elsewhere: {doc['unconverged']}",
    )
    table = Table(
        title="Jacobian of the reduced system (12) at each optimum, by finite differences"
    )
    for column in ("optimum", "eigenvalues (min .. max)", "paper, eq. (13)"):
        table.add_column(column, justify="right")
    for j, values in enumerate(doc["eigenvalues_real"]):
        table.add_row(
            str(j), f"{min(values):.8f} .. {max(values):.8f}", f"{doc['expected_eigenvalue']:g}"
        )
    show(console, table)
    verdict = "confirmed" if doc["confirmed"] else "NOT confirmed"
    say(console, f"max |eigenvalue + 2/T| = {doc['max_eigen_error']:.2e}: {verdict}")
    if "figure" in doc:
        figure_line(console, Path(doc["figure"]), f"phase portrait of system (12), T = {t:g}")


def theory_title(doc: dict[str, Any]) -> tuple[str, str]:
    """The title and settings of one Theorem 1 check."""
    title = f"Theorem 1: {doc['n_agents']} agents, {doc['n_optima']} optimal joint actions"
    settings = f"T = {doc['temperature']:g}, {doc['starts']} random starts, seed {doc['seed']}"
    return title, settings


# ------------------------------------------------------------- the tournament


def _label(name: str, learner: dict[str, Any]) -> str:
    """The algorithm's name, marked * when its settings are not the paper's battlefield
    settings."""
    from cmarlcd import registry
    from cmarlcd.experiments.tournament import battlefield_learners

    paper = battlefield_learners().get(name)
    same = paper is not None and asdict(paper) == learner
    return registry.display_name(name) + ("" if same else " *")


def _pm(mean: float, spread: float, fmt: str) -> str:
    return "—" if np.isnan(mean) else f"{mean:{fmt}} ± {spread:{fmt}}"


def tournament_tables(cells: Sequence[Any], names: dict[str, str], caption: str) -> list[Table]:
    """Fig. 6 and Fig. 7 as tables: rows the algorithm, columns its opponent."""
    table = {(c.algorithm, c.opponent): c for c in cells}
    order = [n for n in names if any(c.algorithm == n for c in cells)]
    rates = Table(
        title="Fig. 6 — win rate (%) of each algorithm (row) against each opponent "
        "(column): win | loss | tie, mean ± spread over rounds",
        caption=caption,
    )
    steps = Table(
        title="Fig. 7 — win steps: mean turns of the won episodes, mean ± spread over rounds",
        caption=caption,
    )
    for t in (rates, steps):
        t.add_column("algorithm")
        for opponent in order:
            t.add_column(f"vs {names[opponent]}", justify="right")
    for algorithm in order:
        rate_row, step_row = [names[algorithm]], [names[algorithm]]
        for opponent in order:
            c = table.get((algorithm, opponent))
            if c is None:
                rate_row.append("—")
                step_row.append("—")
                continue
            rate_row.append(
                f"{_pm(100 * c.win_rate, 100 * c.win_rate_std, '.1f')} | "
                f"{100 * c.loss_rate:.1f} | {100 * c.tie_rate:.1f}"
            )
            step_row.append(_pm(c.win_steps, c.win_steps_std, ".2f"))
        rates.add_row(*rate_row)
        steps.add_row(*step_row)
    return [rates, steps]


def tournament_report(
    records: Sequence[RunRecord], figures: Path, console: Output | None
) -> dict[str, Any]:
    """Figs. 6-7 (tables and PNGs) and the check of the paper's claims, from one
    tournament's stored matches."""
    from cmarlcd import figures as figs
    from cmarlcd.experiments import tournament as tour

    present = {
        name: learner
        for rec in records
        for name, learner in zip(rec.config["algorithms"], rec.config["learners"], strict=True)
    }
    known = list(tour.battlefield_learners())
    order = sorted(present, key=lambda n: (known.index(n) if n in known else len(known), n))
    names = {name: _label(name, present[name]) for name in order}
    cells = match_results.summarize(records, list(names))
    claims = claim_checks.check_claims(records, cells)
    first = records[0]
    rounds = sorted({r.key.run_index for r in records})
    reading = match_results.match_reading(records)
    reading_text = match_results.reading_label(reading)
    settings = (
        f"{len(rounds)} round{'s' if len(rounds) > 1 else ''}, "
        f"{first.config['learn_episodes']:,} learning and "
        f"{first.config['eval_episodes']:,} evaluation episodes per match, seed "
        f"{first.key.root_seed}; readings: {reading_text}"
    )
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    seed = first.key.root_seed
    paths = {}
    for fig, metric, label in ((6, "win_rate", "win rate"), (7, "win_steps", "win steps")):
        stem = f"battlefield-fig{fig}-{metric.replace('_', '-')}-seed{seed}"
        title = f"Fig. {fig} — {label} ({settings})"
        unit = " (turns)" if metric == "win_steps" else ""
        paths[f"fig{fig}"] = figs.tournament_bars(
            cells, metric, label + unit, title, figures / figure_name(stem, group), names
        )
    if console is not None:
        for table in tournament_tables(cells, names, settings):
            show(console, table)
        say(console, "The paper's claims (Section V-B) against these matches:")
        for claim in claims:
            say(console, f"  {claim.claim}: {claim.verdict.upper()} — {claim.evidence}")
        for key, path in paths.items():
            figure_line(console, path, f"Fig. {key[3:]}, {settings}")
    return {
        "experiment": tour.EXPERIMENT,
        "title": "Figs. 6-7: the blood battlefield tournament"
        + ("" if reading_text == "defaults" else f" ({reading_text})"),
        "settings": settings,
        "readings": reading,
        "versions": versions(records, console),
        "seed": seed,
        "rounds": len(rounds),
        "learn_episodes": first.config["learn_episodes"],
        "eval_episodes": first.config["eval_episodes"],
        "cells": [c.to_dict() for c in cells],
        "claims": [c.to_dict() for c in claims],
        "figures": {key: str(path) for key, path in paths.items()},
    }
