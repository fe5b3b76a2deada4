"""The report of ``cmarl-cd scaling``: learners against the size of the sensor network,
its table, its figure (success against the state count) and its JSON."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cmarlcd.experiments import scaling
from cmarlcd.experiments.episodic import run_of
from cmarlcd.experiments.scaling import ScalingRow
from cmarlcd.reports.section import (
    Cell,
    FigureBlock,
    Section,
    TableBlock,
    TextBlock,
    figure_name,
    new_section,
    percent,
)
from cmarlcd.runs import RunRecord

TITLE = "Where tables stop: the sensor network at growing sizes (beyond the paper)"
SUCCESS_NOTE = (
    "Success: the share of greedy evaluation episodes in which every target is captured "
    "within the step cap (20 steps per target). The paper's own success, return 42 in 3 "
    "steps, is defined at its size (2x3 cells, 2 targets) only, and given for it below. "
    "Return per target: the mean return divided by the targets (the paper's "
    "optimum: 21). A network of R x C cells has (R + 1)(C + 1) sensors. The deep "
    "learners read the same state features at every size."
)
COLUMNS = ["size", "states", "learner", "success %", "return / target", "steps"]


def scaling_table(rows: Sequence[ScalingRow], caption: str) -> TableBlock:
    """One line per (size, learner)."""
    lines = [
        [
            Cell(row.size),
            Cell(f"{row.states:,}"),
            Cell(row.label),
            Cell(f"{percent(row.success_rate)} ± {percent(row.std_success)}"),
            Cell(f"{row.return_per_target:.1f}"),
            Cell(f"{row.mean_steps:.1f}"),
        ]
        for row in rows
    ]
    title = "Learners against the size of the network (ROWSxCOLS cells / targets)"
    return TableBlock(title, COLUMNS, lines, caption, layout="compact")


def paper_success_line(rows: Sequence[ScalingRow]) -> str | None:
    """The paper's own success (42 in 3 steps) of each learner at the paper's size."""
    at_paper = [row for row in rows if row.paper_success is not None]
    if not at_paper:
        return None
    found = ", ".join(f"{row.label} {percent(row.paper_success)} %" for row in at_paper)
    return f"At the paper's size, the paper's success (return 42 in 3 steps): {found}."


def series(rows: Sequence[ScalingRow]) -> dict[str, np.ndarray]:
    """Per learner, its sizes as [states, success, std, return per target] rows."""
    by_learner: dict[str, list[list[float]]] = defaultdict(list)
    for row in rows:
        point = [row.states, row.success_rate, row.std_success, row.return_per_target]
        by_learner[row.label].append(point)
    return {label: np.array(sorted(points)) for label, points in by_learner.items()}


def trends(rows: Sequence[ScalingRow]) -> list[str]:
    """Per learner, its success at the smallest and at the largest size played."""
    lines = []
    for label, points in series(rows).items():
        first, last = points[0], points[-1]
        lines.append(
            f"{label}: {percent(first[1])} % at {first[0]:,.0f} states, "
            f"{percent(last[1])} % at {last[0]:,.0f} (return per target {first[3]:.1f} → "
            f"{last[3]:.1f})"
        )
    return lines


def scaling_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """The study's table and figure from its stored runs."""
    rows = scaling.summarize(records)
    settings = run_of(records[0])
    seed = records[0].key.root_seed
    runs = sorted({row.runs for row in rows})
    runs_text = "/".join(map(str, runs))
    protocol = (
        f"L = {settings.largest:,} learning episodes, {runs_text} runs per cell, "
        f"{settings.eval_episodes:,} evaluation episodes, seed {seed}"
    )
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    path = figures / figure_name(f"scaling-seed{seed}", group)
    title = f"The sensor network at growing sizes: {protocol}"
    from cmarlcd.reports import figures as figs

    drawn = figs.scaling_curves(series(rows), title, path)
    section = new_section(
        TITLE,
        protocol,
        records,
        experiment=scaling.EXPERIMENT,
        seed=seed,
        note=SUCCESS_NOTE,
        rows=[row.to_dict() for row in rows],
        figures={"scaling": str(drawn)},
    )
    section.add(TextBlock(SUCCESS_NOTE), scaling_table(rows, protocol))
    paper = paper_success_line(rows)
    if paper is not None:
        section.add(TextBlock(paper))
    section.add(*(TextBlock(line, item=True) for line in trends(rows)))
    section.add(FigureBlock(drawn, "success and return per target against the state count"))
    return section
