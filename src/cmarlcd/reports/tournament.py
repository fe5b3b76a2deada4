"""The report of Figs. 6-7 (``cmarl-cd tournament``): win rates and win steps of each
algorithm against each opponent, the paper's claims checked, the bar charts."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.reports.section import (
    Cell,
    FigureBlock,
    Section,
    TableBlock,
    TextBlock,
    figure_name,
    new_section,
)
from cmarlcd.runs import RunRecord


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
    from cmarlcd.experiments import tournament as tour
    from cmarlcd.reports import figures as figs

    present = {
        learner.name: learner for rec in records for learner in tour.pairing_of(rec).learners
    }
    known = list(tour.battlefield_learners())
    order = sorted(present, key=lambda n: (known.index(n) if n in known else len(known), n))
    names = {name: match_results.side_label(present[name]) for name in order}
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
