"""Stored runs of the learn-then-evaluate protocol (:mod:`~.episodic`) read back: the
rows of Tables 3-7 (one per algorithm, settings and L, aggregated over runs), the
learning curves, and which runs belong in one set of tables."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments.episodic import (
    STD_DDOF,
    TABLE_METRICS,
    EpisodicGame,
    Options,
    anneals_over_budget,
    run_of,
)
from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.deep.epymarl import epymarl_config
from cmarlcd.registry import LearnerConfig
from cmarlcd.runs import RunRecord


@dataclass(frozen=True)
class Row:
    """One (algorithm, L) entry of the tables, aggregated over runs."""

    algorithm: str
    label: str
    """Display name, with the settings that differ from the paper's (``CMARL-CD
    (delta=0.08)``): runs of two settings are two rows."""
    episodes: int
    runs: int
    success_rate: float
    mean_return: float
    std_return: float
    mean_steps: float
    std_steps: float
    min_return: float
    max_steps: float
    paper: dict[str, float | None]
    """The paper's values, only where our settings are the paper's (else None)."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def row_label(learner: LearnerConfig) -> str:
    """The learner's name with the settings that differ from the paper's (its DSN
    settings), e.g. ``CMARL-CD (delta=0.08)``; :func:`cmarlcd.registry.variant_label`.
    A deep learner at EPyMARL's settings (:mod:`cmarlcd.learners.deep.epymarl`) is named
    so, with the settings that differ from those: ``VDN (EPyMARL)``, ``VDN (EPyMARL,
    lr=0.001)``."""
    preset = epymarl_reference(learner)
    if preset is not None:
        changed = registry.changed_settings(learner, preset)
        if len(changed) < len(registry.changed_settings(learner)):
            words = "".join(f", {k}={v}" for k, v in sorted(changed.items()))
            return f"{registry.display_name(learner.name)} (EPyMARL{words})"
    return registry.variant_label(learner)


def epymarl_reference(learner: LearnerConfig) -> DeepConfig | None:
    """EPyMARL's settings for ``learner`` (a :class:`DeepConfig`) on the task its training
    rhythm says (one gradient step per episode: ``train_every`` is the episode's steps)."""
    if not isinstance(learner, DeepConfig):
        return None
    reference = registry.reference_settings(learner)
    if not isinstance(reference, DeepConfig):
        return None
    preset = epymarl_config(reference, learner.train_every)
    return replace(preset, negative_rate=learner.negative_rate)


def summarize(game: EpisodicGame, records: Iterable[RunRecord]) -> list[Row]:
    """The tables from stored runs: one row per (algorithm, settings, L)."""
    per_cell: dict[tuple[str, str, int], dict[int, dict[str, float]]] = defaultdict(dict)
    as_paper: dict[str, bool] = {}
    for rec in records:
        settings = run_of(rec)
        label = row_label(settings.learner) + options_label(settings.options)
        as_paper[label] = registry.is_paper_setting(settings.learner) and not settings.options
        for budget, result in rec.metrics["checkpoints"].items():
            # keyed by run: sweeps with other checkpoint lists hold the very same run at L
            per_cell[(rec.key.algorithm, label, int(budget))][rec.key.run_index] = result
    rows = []
    for (name, label, budget), by_run in sorted(per_cell.items(), key=_row_order):
        results = list(by_run.values())
        success = np.array([r["success_rate"] for r in results])
        returns = np.array([r["mean_return"] for r in results])
        steps = np.array([r["mean_steps"] for r in results])
        paper = as_paper[label]
        rows.append(
            Row(
                algorithm=name,
                label=label,
                episodes=budget,
                runs=len(results),
                success_rate=float(success.mean()),
                mean_return=float(returns.mean()),
                std_return=float(returns.std(ddof=STD_DDOF)),
                mean_steps=float(steps.mean()),
                std_steps=float(steps.std(ddof=STD_DDOF)),
                min_return=float(returns.min()),
                max_steps=float(steps.max()),
                paper={
                    m: game.paper_value(name, budget, m) if paper else None for m in TABLE_METRICS
                },
            )
        )
    return rows


def _row_order(item: tuple[tuple[str, str, int], Any]) -> tuple[int, str, int]:
    (name, label, budget), _ = item
    known = list(registry.LEARNERS)
    return (known.index(name) if name in known else len(known), label, budget)


def learning_curves(records: Iterable[RunRecord]) -> dict[str, np.ndarray]:
    """Per row label, an array (runs, points, 4) of [episodes, success, return, steps]."""
    curves: dict[str, list[list[list[float]]]] = defaultdict(list)
    for rec in records:
        settings = run_of(rec)
        label = row_label(settings.learner) + options_label(settings.options)
        if anneals_over_budget(settings.learner):
            label += f", L = {settings.largest:,}"
        curves[label].append(rec.metrics["curve"])
    return {label: np.array(runs) for label, runs in curves.items() if runs and runs[0]}


def protocol_key(record: RunRecord) -> tuple:
    """Runs that belong in one set of tables: same seed and evaluation settings."""
    settings = run_of(record)
    fields = ("eval_episodes", "curve_points", "curve_eval_episodes", "options")
    return (record.key.root_seed, *(str(getattr(settings, f)) for f in fields))


def options_label(options: Options) -> str:
    """How a row names a game's options (nothing for the game as the paper plays it)."""
    return "".join(f", {name} {_option_text(value)}" for name, value in options)


def _option_text(value: Any) -> str:
    return "x".join(map(str, value)) if isinstance(value, tuple) else str(value)
