"""The report of ``cmarl-cd train --game``: learning curves on a compiled game beside the
uniform random policy's return, a table of the final greedy returns and its JSON (with,
per learner, the field's maximum and average return of its curve:
:mod:`cmarlcd.experiments.field_metrics`)."""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cmarlcd.experiments import games, settings_of
from cmarlcd.experiments.episodic import STD_DDOF
from cmarlcd.experiments.episodic_results import row_label
from cmarlcd.experiments.field_metrics import field_metrics
from cmarlcd.reports.section import (
    FigureBlock,
    Section,
    TableBlock,
    TextBlock,
    cells,
    figure_name,
    new_section,
)
from cmarlcd.runs import RunRecord

RANDOM_LABEL = "random policy"


@dataclass(frozen=True)
class FinalRow:
    """One learner's greedy evaluation after its whole budget, over its runs (or the
    random policy's, one sample of ``runs`` episodes)."""

    algorithm: str
    label: str
    runs: int
    mean_return: float
    std_return: float
    success_rate: float
    mean_steps: float
    above_random: float

    def to_dict(self) -> dict:
        return self.__dict__.copy()


def _groups(records: Sequence[RunRecord]) -> dict[str, list[RunRecord]]:
    groups: dict[str, list[RunRecord]] = defaultdict(list)
    for rec in sorted(records, key=lambda r: (r.key.algorithm, r.key.config)):
        groups[row_label(settings_of(rec).learner)].append(rec)
    return groups


def _final(record: RunRecord) -> dict[str, float]:
    points = record.metrics["checkpoints"]
    return points[str(max(int(budget) for budget in points))]


def game_training_section(records: Sequence[RunRecord], figures: Path, seed: int) -> Section:
    """The curves and final returns of one study on a task of a compiled game, with the
    uniform random policy's return as the floor."""
    from cmarlcd.reports import figures as figs

    first = settings_of(records[0])
    family = games.FAMILIES[records[0].key.experiment]
    rules = family.rules_of(first.options)
    budget, episodes = first.largest, first.eval_episodes
    floor_episodes = max(episodes, games.FLOOR_EPISODES)
    floor = games.uniform_floor(rules, floor_episodes, seed)
    floor_return = float(floor.returns.mean())
    rows = [
        FinalRow(
            "random",
            RANDOM_LABEL,
            floor_episodes,
            floor_return,
            float(floor.returns.std()),
            float(floor.terminated.mean()),
            float(floor.lengths.mean()),
            0.0,
        )
    ]
    curves: dict[str, np.ndarray] = {}
    for label, runs in _groups(records).items():
        finals = [_final(r) for r in runs]
        returns = np.array([f["mean_return"] for f in finals])
        rows.append(
            FinalRow(
                runs[0].key.algorithm,
                label,
                len(runs),
                float(returns.mean()),
                float(returns.std(ddof=STD_DDOF)),
                float(np.mean([f["success_rate"] for f in finals])),
                float(np.mean([f["mean_steps"] for f in finals])),
                float(returns.mean()) - floor_return,
            )
        )
        curves[label] = np.array([[[p[0], p[2], p[3]] for p in r.metrics["curve"]] for r in runs])
    if curves:
        x = next(iter(curves.values()))[0, :, 0]
        flat = [[point, floor_return, floor.lengths.mean()] for point in x]
        curves = {RANDOM_LABEL: np.array([flat]), **curves}
    field = field_figures(curves, return_column=1)
    where = f"{family.name} {rules.name}"
    steps = first.unit == "steps"
    learnt = f"{budget:,} environment steps" if steps else f"L = {budget:,} episodes"
    inputs = dict(first.options).get("inputs", "observations")
    time_left = games.reads_time_left(first.options)
    read = (
        "each agent its own observation"
        if inputs == "own-observations"
        else "every agent's observation"
    ) + (" and the time left" if time_left else "")
    team = "mean" if getattr(rules, "reward", "sum") == "mean" else "sum"
    protocol = (
        f"{learnt}, deep learners reading {read}, greedy return over {episodes:,} episodes "
        f"at the end and {first.curve_eval_episodes:,} at {first.curve_points} points of the "
        f"curve{' and before learning' if first.eval_at_start else ''}, team reward = the "
        f"{team} of the agents', seed {seed}; the random policy: "
        f"{floor_episodes:,} episodes of uniform legal actions"
    )
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    stem = re.sub(r"[^A-Za-z0-9.-]+", "_", f"train-{family.name}-{rules.name}-seed{seed}")
    path = figures / figure_name(stem, group)
    drawn = figs.environment_curves(curves, RANDOM_LABEL, where, path, first.unit)
    success = family.success
    columns = ["learner", "runs", "return", "vs random", *([success] if success else []), "steps"]
    table = TableBlock(
        f"Greedy return after {learnt} on {where}",
        columns,
        [
            cells(
                r.label,
                str(r.runs) if r.algorithm != "random" else "-",
                f"{r.mean_return:.3f} ± {r.std_return:.3f}",
                f"{r.above_random:+.3f}",
                *([f"{100 * r.success_rate:.1f} %"] if success else []),
                f"{r.mean_steps:.1f}",
            )
            for r in rows
        ],
        protocol,
        layout="compact",
    )
    field_table = field_figures_table(field, where, first.unit)
    section = new_section(
        f"Learning on {where} (beyond the paper)",
        protocol,
        records,
        experiment=family.name,
        game=f"{family.name}:{rules.name}",
        inputs=inputs,
        time_left=time_left,
        budget=budget,
        unit=first.unit,
        seed=seed,
        rows=[r.to_dict() for r in rows],
        curves={label: data.tolist() for label, data in curves.items()},
        field={label: m.as_dict() for label, m in field.items()},
        figures={"curves": str(drawn)},
    )
    section.add(
        table,
        TextBlock(
            "Mean over runs; ± the spread over runs (population std; for the random policy, "
            "over its episodes)."
            + (
                f" {success}: the evaluation episodes that ended before the step cap."
                if success
                else ""
            )
        ),
        field_table,
        FigureBlock(
            drawn, f"greedy return against {'environment steps' if steps else 'learning episodes'}"
        ),
    )
    return section


def field_figures(curves: dict[str, np.ndarray], return_column: int) -> dict[str, Any]:
    """Each learner's (not the random policy's) field figures of its curves ``(runs,
    points, columns)``: column 0 the budgets, ``return_column`` the greedy return
    (:func:`cmarlcd.experiments.field_metrics.field_metrics`)."""
    return {
        label: field_metrics(data[0, :, 0].astype(int), data[:, :, return_column])
        for label, data in curves.items()
        if label != RANDOM_LABEL
    }


def field_figures_table(field: dict[str, Any], where: str, unit: str) -> TableBlock:
    """The field's figures of :func:`field_figures` as a table."""
    interval = "95 % interval"
    return TableBlock(
        f"The field's figures of the curves on {where}",
        ["learner", "max return", interval, f"at ({unit})", "average return", interval],
        [
            cells(
                label,
                f"{m.max_return:.3f}",
                f"[{m.max_return_low:.3f}, {m.max_return_high:.3f}]",
                f"{m.max_return_at:,}",
                f"{m.average_return:.3f}",
                f"[{m.average_return_low:.3f}, {m.average_return_high:.3f}]",
            )
            for label, m in field.items()
        ],
        "max return: the point of the curve whose mean over runs is highest; average return: "
        "the mean over every point; intervals: Student's t over the runs (EPyMARL's figures)",
        layout="compact",
    )
