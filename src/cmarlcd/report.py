"""Reports of stored runs as data: paper-style tables, their figures, their JSON.

Each ``*_section`` function takes the stored records of one group of runs (one table's
worth), draws its figures into a folder (:mod:`cmarlcd.figures`) and returns a
:class:`~cmarlcd.section.Section`: title, settings, the package versions its runs were
computed by, tables whose cells hold our values beside the paper's, notes, figures and
the group's JSON fields. :mod:`cmarlcd.render` prints a section on a terminal,
:mod:`cmarlcd.document` writes it as Markdown or HTML. Figure files are named by what
they show: a readable stem and a digest of the group's settings, so groups with other
settings never overwrite each other; each figure's caption says which settings it shows.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments import episodic, episodic_results
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.experiments.episodic import EpisodicGame
from cmarlcd.experiments.episodic_results import Row
from cmarlcd.experiments.repeated import CellSummary
from cmarlcd.section import BAD, GOOD, Cell, FigureBlock, Section, TableBlock, TextBlock, cells
from cmarlcd.store import RunRecord

#: Success rates below this are shown in red (the acceptance bar for Tables 1-2).
SUCCESS_BAR = 0.96


def percent(rate: float | None) -> str:
    """``0.98`` -> ``"98"``; keeps one decimal when it matters (``"97.5"``)."""
    if rate is None:
        return "—"
    value = 100.0 * rate
    return f"{value:.0f}" if abs(value - round(value)) < 1e-9 else f"{value:.1f}"


def versions(records: Sequence[RunRecord]) -> Counter:
    """Runs per package version."""
    return Counter(rec.version for rec in records)


def new_section(title: str, settings: str, records: Sequence[RunRecord], **data: Any) -> Section:
    """An empty section of ``records`` (their versions and count) with JSON fields."""
    unique = {rec.key: rec for rec in records}
    return Section(title, settings, versions(list(unique.values())), len(unique), data=data)


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
    cells_: Sequence[CellSummary],
    title: str,
    render: Callable[[CellSummary], Cell],
    caption: str = "",
) -> TableBlock:
    """The paper's layout: one row per action count m, one column per agent count n."""
    agents = sorted({c.agents for c in cells_})
    actions = sorted({c.actions for c in cells_})
    by_cell = {(c.agents, c.actions): c for c in cells_}
    rows = [
        [Cell(f"m={m}")]
        + [Cell("") if (n, m) not in by_cell else render(by_cell[(n, m)]) for n in agents]
        for m in actions
    ]
    return TableBlock(title, ["", *(f"n={n}" for n in agents)], rows, caption)


def _success(cell: CellSummary) -> Cell:
    tone = GOOD if cell.success_rate >= SUCCESS_BAR else BAD
    paper = None if cell.paper_success_rate is None else percent(cell.paper_success_rate)
    return Cell(percent(cell.success_rate), paper, tone)


def _median_games(cell: CellSummary) -> Cell:
    return Cell("—" if cell.median_games is None else f"{cell.median_games:,.0f}")


def success_table(cells_: Sequence[CellSummary], title: str) -> TableBlock:
    """Success rate per cell, beside the paper's when the settings are the paper's."""
    paper = any(c.paper_success_rate is not None for c in cells_)
    what = "ours (the paper's)" if paper else "ours (settings differ from the paper's)"
    caption = f"success % per cell: {what}; rows: actions m, columns: agents n"
    return _grid_table(cells_, title, _success, caption)


def games_table(cells_: Sequence[CellSummary], title: str) -> TableBlock:
    """Median games to convergence per cell (the paper does not report it)."""
    return _grid_table(cells_, title, _median_games)


def repeated_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """Table 1 or 2 and its heatmap from the records of one group of runs."""
    from cmarlcd import figures as figs

    summary = rep.summarize(records)
    title = rep.table_title(records)
    cell, seed = rep.cell_of(records[0]), records[0].key.root_seed
    case = cell.case
    name = figure_name(f"repeated-case{case}-seed{seed}", rep.group_key(cell, seed))
    path = figs.repeated_heatmap(summary, title, figures / name)
    settings = rep.settings_text(records)
    section = new_section(
        f"Table {case}: random cooperative repeated games, case {case}",
        settings,
        records,
        experiment=rep.EXPERIMENT,
        case=case,
        seed=seed,
        figure=str(path),
        cells=[c.to_dict() for c in summary],
    )
    section.add(
        success_table(summary, title),
        games_table(summary, f"Median games to convergence ({settings})"),
        FigureBlock(path, settings),
    )
    return section


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


def dsn_tables(rows: Sequence[Row], protocol: str = "") -> list[TableBlock]:
    """Tables 3-7 in the paper's layout: algorithms by row, L by column; ours, and the
    paper's under it for the rows run with the paper's settings."""
    budgets = sorted({r.episodes for r in rows})
    labels = list(dict.fromkeys(r.label for r in rows))
    by_cell = {(r.label, r.episodes): r for r in rows}
    paper = any(v is not None for r in rows for v in r.paper.values())
    suffix = f" ({protocol})" if protocol else ""
    tables = []
    for number, title, metrics, fmt in DSN_TABLES:
        body = []
        for label in labels:
            row = [Cell(label)]
            for budget in budgets:
                found = by_cell.get((label, budget))
                if found is None:
                    row.append(Cell(""))
                    continue
                ours = " | ".join(_format(getattr(found, m), fmt) for m in metrics)
                theirs = None
                if any(found.paper[m] is not None for m in metrics):
                    theirs = " | ".join(_format(found.paper[m], fmt) for m in metrics)
                row.append(Cell(ours, theirs))
            body.append(row)
        columns = ["ours\n(paper)" if paper else "ours", *(f"L = {b:,}" for b in budgets)]
        tables.append(
            TableBlock(
                f"Table {number}. {title}{suffix}", columns, body, paper_below=True, layout="lines"
            )
        )
    return tables


TRAIN_ONCE_NOTE = (
    "CMARL-CD and LA-OCA do not depend on L: each run trains once to the largest L and is "
    "evaluated at every L on the way. VDN and QMIX anneal ε over L (eq. 18), so each L is "
    "a run of its own."
)


def protocol_text(records: Sequence[RunRecord], rows: Sequence[Row]) -> str:
    """What the tables of a group show: seed, runs per cell, evaluation episodes."""
    evaluations = episodic.run_of(records[0]).eval_episodes
    runs = runs_text([r.runs for r in rows], "cell")
    return f"seed {records[0].key.root_seed}, {runs}, {evaluations:,} evaluation episodes"


def dsn_section(game: EpisodicGame, records: Sequence[RunRecord], figures: Path) -> Section:
    """Tables 3-7, the learning curves and Fig. 4 of one group of DSN runs."""
    from cmarlcd import figures as figs

    rows = episodic_results.summarize(game, records)
    seed = records[0].key.root_seed
    protocol = protocol_text(records, rows)
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    curves_name = figure_name(f"dsn-learning-curves-seed{seed}", group)
    curves = figs.learning_curves(episodic_results.learning_curves(records), figures / curves_name)
    paths = {"learning_curves": str(curves)}
    shown = {"learning_curves": f"learning curves, {protocol}"}
    options = episodic.run_of(records[0]).options
    for rec in records:
        if rec.key.run_index == 0 and rec.metrics["policy"]:  # a larger network stores none
            settings = episodic.run_of(rec)
            label, largest = episodic_results.row_label(settings.learner), settings.largest
            what = f"{label}, L = {largest:,}, seed {seed}, run 0"
            title = f"Fig. 4 — greedy joint action of {what} in each of the 42 states"
            stem = f"dsn-fig4-{rec.key.algorithm}-L{largest}-seed{seed}"
            path = figs.dsn_policy_grid(
                np.array(rec.metrics["policy"]), title, figures / figure_name(stem, rec.key.config)
            )
            key = f"fig4_{rec.key.algorithm}_L{largest}"
            if label != registry.display_name(rec.key.algorithm):  # one figure per setting
                key += "_" + figure_name("", rec.key.config)[1:9]
            paths[key], shown[key] = str(path), f"Fig. 4, {what}"
    title = "Tables 3-7 and Fig. 4: the distributed sensor network task"
    if options:  # beyond the paper: success is every target captured within the cap
        size = episodic_results.options_label(options)
        title = f"The distributed sensor network{size} (beyond the paper)"
        protocol += "; success: every target captured within the step cap"
    section = new_section(
        title,
        protocol,
        records,
        experiment=game.experiment,
        seed=seed,
        note=TRAIN_ONCE_NOTE,
        rows=[r.to_dict() for r in rows],
        figures=paths,
    )
    section.add(TextBlock(TRAIN_ONCE_NOTE), *dsn_tables(rows, protocol))
    section.add(*(FigureBlock(Path(path), shown[key]) for key, path in paths.items()))
    return section


# ------------------------------------------------------------------- Theorem 1


def theory_section(doc: dict[str, Any], records: Sequence[RunRecord] = ()) -> Section:
    """Where the ODE starts went, and the Jacobian's eigenvalues against eq. (13), of one
    Theorem 1 check (``records``: the stored run it comes from, if any)."""
    t = doc["temperature"]
    title = f"Theorem 1: {doc['n_agents']} agents, {doc['n_optima']} optimal joint actions"
    settings = f"T = {t:g}, {doc['starts']} random starts, seed {doc['seed']}"
    section = new_section(title, settings, records, **doc)
    reached = ", ".join(f"optimum {j}: {k}" for j, k in enumerate(doc["converged_to"]))
    section.add(
        TextBlock(
            f"ODE (8) from {doc['starts']} random interior starts -> {reached}; "
            f"elsewhere: {doc['unconverged']}"
        )
    )
    rows = [
        cells(str(j), f"{min(v):.8f} .. {max(v):.8f}", f"{doc['expected_eigenvalue']:g}")
        for j, v in enumerate(doc["eigenvalues_real"])
    ]
    section.add(
        TableBlock(
            "Jacobian of the reduced system (12) at each optimum, by finite differences",
            ["optimum", "eigenvalues (min .. max)", "paper, eq. (13)"],
            rows,
        )
    )
    verdict = "confirmed" if doc["confirmed"] else "NOT confirmed"
    section.add(TextBlock(f"max |eigenvalue + 2/T| = {doc['max_eigen_error']:.2e}: {verdict}"))
    if "figure" in doc:
        section.add(FigureBlock(Path(doc["figure"]), f"phase portrait of system (12), T = {t:g}"))
    return section


# ------------------------------------------------------------- the tournament


def _label(learner: Any) -> str:
    """The algorithm's name, with the settings that differ from its battlefield settings
    (readings aside: the section's title names them)."""
    return match_results.side_label(learner)


def _pm(mean: float, spread: float, fmt: str) -> str:
    return "—" if np.isnan(mean) else f"{mean:{fmt}} ± {spread:{fmt}}"


def tournament_tables(
    cells_: Sequence[Any], names: dict[str, str], caption: str
) -> list[TableBlock]:
    """Fig. 6 and Fig. 7 as tables: rows the algorithm, columns its opponent."""
    table = {(c.algorithm, c.opponent): c for c in cells_}
    order = [n for n in names if any(c.algorithm == n for c in cells_)]
    rate_rows, step_rows = [], []
    for algorithm in order:
        rate_row, step_row = [Cell(names[algorithm])], [Cell(names[algorithm])]
        for opponent in order:
            c = table.get((algorithm, opponent))
            if c is None:
                rate_row.append(Cell("—"))
                step_row.append(Cell("—"))
                continue
            rate_row.append(
                Cell(
                    f"{_pm(100 * c.win_rate, 100 * c.win_rate_std, '.1f')} | "
                    f"{100 * c.loss_rate:.1f} | {100 * c.tie_rate:.1f}"
                )
            )
            step_row.append(Cell(_pm(c.win_steps, c.win_steps_std, ".2f")))
        rate_rows.append(rate_row)
        step_rows.append(step_row)
    columns = ["algorithm", *(f"vs {names[o]}" for o in order)]
    return [
        TableBlock(
            "Fig. 6 — win rate (%) of each algorithm (row) against each opponent "
            "(column): win | loss | tie, mean ± spread over rounds",
            columns,
            rate_rows,
            caption,
        ),
        TableBlock(
            "Fig. 7 — win steps: mean turns of the won episodes, mean ± spread over rounds",
            columns,
            step_rows,
            caption,
        ),
    ]


def tournament_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """Figs. 6-7 (tables and PNGs) and the check of the paper's claims, from one
    tournament's stored matches."""
    from cmarlcd import figures as figs
    from cmarlcd.experiments import tournament as tour

    present = {
        learner.name: learner for rec in records for learner in tour.pairing_of(rec).learners
    }
    known = list(tour.battlefield_learners())
    order = sorted(present, key=lambda n: (known.index(n) if n in known else len(known), n))
    names = {name: _label(present[name]) for name in order}
    summary = match_results.summarize(records, list(names))
    claims = claim_checks.check_claims(records, summary)
    first, pairing = records[0], tour.pairing_of(records[0])
    rounds = sorted({r.key.run_index for r in records})
    reading = match_results.match_reading(records)
    reading_text = match_results.reading_label(reading)
    settings = (
        f"{len(rounds)} round{'s' if len(rounds) > 1 else ''}, "
        f"{pairing.learn_episodes:,} learning and "
        f"{pairing.eval_episodes:,} evaluation episodes per match, seed "
        f"{first.key.root_seed}; readings: {reading_text}"
    )
    own = [label for name, label in names.items() if label != registry.display_name(name)]
    if own:  # sides with settings of their own (``--set``): the captions name them
        settings += f"; settings: {'; '.join(own)}"
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    seed = first.key.root_seed
    paths = {}
    for fig, metric, label in ((6, "win_rate", "win rate"), (7, "win_steps", "win steps")):
        stem = f"battlefield-fig{fig}-{metric.replace('_', '-')}-seed{seed}"
        title = f"Fig. {fig} — {label} ({settings})"
        unit = " (turns)" if metric == "win_steps" else ""
        paths[f"fig{fig}"] = figs.tournament_bars(
            summary, metric, label + unit, title, figures / figure_name(stem, group), names
        )
    section = new_section(
        "Figs. 6-7: the blood battlefield tournament"
        + ("" if reading_text == "defaults" else f" ({reading_text})"),
        settings,
        records,
        experiment=tour.EXPERIMENT,
        readings=reading,
        seed=seed,
        rounds=len(rounds),
        learn_episodes=pairing.learn_episodes,
        eval_episodes=pairing.eval_episodes,
        labels=names,
        cells=[c.to_dict() for c in summary],
        claims=[c.to_dict() for c in claims],
        figures={key: str(path) for key, path in paths.items()},
    )
    section.add(*tournament_tables(summary, names, settings))
    section.add(TextBlock("The paper's claims (Section V-B) against these matches:"))
    section.add(
        *(TextBlock(f"{c.claim}: {c.verdict.upper()} — {c.evidence}", item=True) for c in claims)
    )
    section.add(*(FigureBlock(p, f"Fig. {key[3:]}, {settings}") for key, p in paths.items()))
    return section
