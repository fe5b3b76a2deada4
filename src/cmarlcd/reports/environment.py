"""The report of ``cmarl-cd train``: learning curves on a PettingZoo environment beside a
uniform random policy, a table of the final returns and its JSON."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cmarlcd.experiments import environment as envs
from cmarlcd.experiments import settings_of
from cmarlcd.experiments.episodic import STD_DDOF
from cmarlcd.experiments.episodic_results import row_label
from cmarlcd.reports.game_training import field_figures, field_figures_table
from cmarlcd.reports.section import (
    FigureBlock,
    Section,
    TableBlock,
    TextBlock,
    cells,
    figure_name,
    new_section,
)
from cmarlcd.runs import RunRecord, canonical_json


@dataclass(frozen=True)
class FinalReturn:
    """One learner's greedy return after the whole budget, over its runs."""

    algorithm: str
    label: str
    runs: int
    mean_return: float
    std_return: float
    mean_steps: float
    above_random: float
    """Mean return minus the random policy's."""

    def to_dict(self) -> dict:
        return self.__dict__.copy()


RANDOM_LABEL = "random policy"


def _label(record: RunRecord) -> str:
    """The learner's name, marked * when its settings are not its defaults."""
    learner = settings_of(record).learner
    return RANDOM_LABEL if learner is None else row_label(learner)


def _by_learner(records: Sequence[RunRecord]) -> dict[tuple[str, str], list[RunRecord]]:
    """Runs by (label, learner settings), the random policy first; a label that two
    settings share is numbered."""
    groups: dict[tuple[str, str], list[RunRecord]] = defaultdict(list)
    for rec in sorted(records, key=lambda r: (r.key.algorithm != envs.RANDOM, r.key.algorithm)):
        groups[(_label(rec), rec.key.config)].append(rec)
    seen: dict[str, int] = defaultdict(int)
    named = {}
    for (label, config), runs in groups.items():
        seen[label] += 1
        named[(label if seen[label] == 1 else f"{label} ({seen[label]})", config)] = runs
    return named


def curves(records: Sequence[RunRecord]) -> dict[str, np.ndarray]:
    """Per learner (the random policy first), (runs, points, 3): [episodes, return, steps]."""
    return {
        label: np.array([r.metrics["curve"] for r in runs])
        for (label, _), runs in _by_learner(records).items()
    }


def final_returns(records: Sequence[RunRecord]) -> list[FinalReturn]:
    """Each learner's last curve point over its runs, against the random policy's."""
    groups = _by_learner(records)
    random = [r.metrics["curve"][-1] for (label, _), runs in groups.items()
              if label == RANDOM_LABEL for r in runs]  # fmt: skip
    baseline = float(np.mean([p[1] for p in random])) if random else float("nan")
    rows = []
    for (label, _), runs in groups.items():
        points = [r.metrics["curve"][-1] for r in runs]
        returns = np.array([p[1] for p in points])
        rows.append(
            FinalReturn(
                runs[0].key.algorithm,
                label,
                len(points),
                float(returns.mean()),
                float(returns.std(ddof=STD_DDOF)),
                float(np.mean([p[2] for p in points])),
                float(returns.mean()) - baseline,
            )
        )
    return rows


def protocol_key(record: RunRecord) -> tuple:
    """Runs of one study: same environment, budgets, choices and seed."""
    s = settings_of(record)
    kwargs = canonical_json(dict(s.env_kwargs))
    return (s.env, kwargs, s.episodes, s.eval_episodes, s.curve_points, s.reward, s.inputs,
            s.envs, s.unit, s.eval_at_start, record.key.root_seed)  # fmt: skip


def _first_point(settings: envs.EnvRun) -> str:
    return " (the first before learning)" if settings.eval_at_start else ""


def _copies(count: int) -> str:
    return "one copy of the environment at a time" if count == 1 else f"{count} copies at once"


def learned_nothing(records: Sequence[RunRecord]) -> list[str]:
    """A line for each deep CMARL-CD whose memory kept nothing in some runs (``stored``
    0): their networks never took a gradient step, and their curve is that of their
    initial weights."""
    lines = []
    for (label, _), group in _by_learner(records).items():
        empty = [
            r for r in group if r.key.algorithm == "deep-cmarl-cd" and r.metrics.get("stored") == 0
        ]
        if empty:
            lines.append(
                f"{label}: {len(empty)} of {len(group)} runs kept nothing to learn from (an "
                "empty memory: every return fell below the record network's untrained "
                "estimate), so their networks never learned and their curve is that of "
                "their initial weights (unseen_record=estimate-once-kept or first-visit keep "
                "the first episodes)"
            )
    return lines


def environment_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """The learning curves and final returns of one study."""
    from cmarlcd.reports import figures as figs

    first = settings_of(records[0])
    seed = records[0].key.root_seed
    where = f"{first.env}({envs.kwargs_text(first.env_kwargs)})"
    steps = first.unit == "steps"
    learnt = (
        f"{first.episodes:,} environment steps" if steps else f"L = {first.episodes:,} episodes"
    )
    protocol = (
        f"{learnt}, greedy return over {first.eval_episodes:,} "
        f"episodes at {len(first.points())} points{_first_point(first)}, team reward = "
        f"{first.reward} of the "
        f"agents', inputs: {first.inputs}, {_copies(first.envs)}, seed {seed}"
    )
    rows = final_returns(records)
    field = field_figures(curves(records), return_column=1)
    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    path = figures / figure_name(f"train-seed{seed}", group)
    drawn = figs.environment_curves(curves(records), RANDOM_LABEL, where, path, first.unit)
    table = TableBlock(
        f"Greedy return after {learnt}",
        ["learner", "runs", "return", "vs random", "steps"],
        [
            cells(
                r.label,
                str(r.runs),
                f"{r.mean_return:.2f} ± {r.std_return:.2f}",
                f"{r.above_random:+.2f}",
                f"{r.mean_steps:.1f}",
            )
            for r in rows
        ],
        protocol,
        layout="compact",
    )
    section = new_section(
        f"Learning on {where} (beyond the paper)",
        protocol,
        records,
        experiment=envs.EXPERIMENT,
        env=first.env,
        env_kwargs=dict(first.env_kwargs),
        seed=seed,
        unit=first.unit,
        rows=[r.to_dict() for r in rows],
        curves={label: data.tolist() for label, data in curves(records).items()},
        field={label: m.as_dict() for label, m in field.items()},
        figures={"curves": str(drawn)},
    )
    section.add(table, TextBlock("Mean over runs; ± the spread over runs (population std)."))
    section.add(field_figures_table(field, where, first.unit))
    for warning in learned_nothing(records):
        section.add(TextBlock(warning))
    against = "environment steps" if steps else "learning episodes"
    section.add(FigureBlock(drawn, f"greedy return against {against}"))
    return section
