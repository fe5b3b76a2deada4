"""The report of the battlefield readings study (:mod:`cmarlcd.experiments.readings`):
one table of reading × claim, the hit-rate and γ dials as figures, the reading the study
points to, and its JSON."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from cmarlcd import registry
from cmarlcd.experiments import readings as study
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_claims as claim_checks
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.experiments.readings import Outcome, dialled, stored_studies
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

TITLE = "Figs. 6-7 under each reading of Section V-B: which choices decide the claims"
#: Column headings of the claims, in :data:`claim_checks.CLAIMS` order.
SHORT = (
    "CMARL-CD beats every other",
    "QMIX beats LA-OCA",
    "VDN beats LA-OCA",
    "QMIX < 40 % vs CMARL-CD",
    "VDN < 40 % vs CMARL-CD",
    "CMARL-CD fewest win steps",
)
#: How the margins of each claim are written: scale and unit (win rates in percentage
#: points, win steps in turns).
SCALES = (100.0, 100.0, 100.0, 100.0, 100.0, 1.0)


def _initials(name: str) -> str:
    return {"cmarl-cd": "CD", "la-oca": "LA", "vdn": "VDN", "qmix": "QMIX"}.get(
        name, registry.display_name(name)
    )


def margin_text(claim: claim_checks.Claim, scale: float) -> str:
    """``contradicted: LA -6.9±8.2; VDN -23.0±10.3``: the verdict, then each margin and
    two standard errors (one margin: no opponent named)."""
    if claim.verdict == claim_checks.NOT_CHECKED:
        return "not checked"
    digits = 1 if scale > 1 else 2
    parts = []
    for m in claim.margins:
        if m.rounds == 0:
            parts.append(f"{_initials(m.against)} —")
            continue
        two = claim_checks.STANDARD_ERRORS * m.standard_error * scale
        number = f"{m.value * scale:+.{digits}f}±{two:.{digits}f}"
        parts.append(number if len(claim.margins) == 1 else f"{_initials(m.against)} {number}")
    return f"{claim.verdict}: " + "; ".join(parts)


def study_table(outcomes: Sequence[Outcome], caption: str) -> TableBlock:
    """Reading × claim: each claim's verdict and margins (± two standard errors)."""
    rows = []
    for found in outcomes:
        claims = {c.claim: c for c in found.claims}
        margins = [
            Cell(margin_text(claims[text], scale))
            for text, scale in zip(claim_checks.CLAIMS, SCALES, strict=True)
        ]
        score = "—" if math.isnan(found.score) else f"{100 * found.score:+.1f}"
        rows.append([Cell(found.reading.name), Cell(score), *margins])
    return TableBlock(
        "The paper's claims under each reading: verdict, then each margin ± 2 standard "
        "errors over rounds (win rates in points, win steps in turns; > 0: as the paper says)",
        ["reading", "CMARL-CD's mean margin", *SHORT],
        rows,
        caption,
        prose=True,
    )


def readings_section(outcomes: Sequence[Outcome], figures: Path) -> Section:
    """The study's table, its dials' figures (a dial played at two or more points), the
    reading it points to, and its JSON, from its tournaments' stored matches."""
    first = outcomes[0].records[0]
    pairing = tour.pairing_of(first)
    rounds = max(len({r.key.run_index for r in o.records}) for o in outcomes)
    settings = (
        f"{len(outcomes)} tournaments of up to {rounds} round{'s' if rounds != 1 else ''}, "
        f"{pairing.learn_episodes:,} learning and {pairing.eval_episodes:,} "
        f"evaluation episodes per match, seed {first.key.root_seed}"
    )
    records = [rec for o in outcomes for rec in o.records]
    margins = study.gamma_margins(outcomes)
    paths = _dial_figures(outcomes, records, margins, settings, figures)
    pointed = _pointed_to(outcomes)
    section = new_section(
        TITLE,
        settings,
        records,
        experiment="tournament-readings",
        readings=[
            {
                "name": o.reading.name,
                "kind": o.reading.kind,
                "readings": o.reading.readings.as_reading(),
                "rounds": len({r.key.run_index for r in o.records}),
                "matches": len(o.records),
                "main_margin": None if math.isnan(o.score) else o.score,
                "cells": [c.to_dict() for c in o.cells],
                "claims": [c.to_dict() for c in o.claims],
            }
            for o in outcomes
        ],
        gamma_dial=[m.to_dict() for m in margins],
        points_to=None if pointed is None else {
            "name": pointed.name,
            "readings": pointed.readings.as_reading(),
            "tournament_options": study.tournament_options(pointed.readings),
        },
        figures={key: str(path) for key, path in paths.items()},
    )  # fmt: skip
    section.add(
        study_table(outcomes, settings),
        TextBlock(
            "CMARL-CD's mean margin: its win rate minus its opponent's, averaged over the "
            f"other algorithms (points). The defaults: {defaults_text()}."
        ),
    )
    if pointed is not None:
        section.add(TextBlock(_pointed_text(pointed, outcomes)))
    bars = "± 2 standard errors" if rounds > 1 else "one round: no error bars"
    captions = {
        "hit_rates": f"win rate against hit rate, {settings}",
        "gamma": f"each tabular learner's margin against γ ({bars}), {settings}",
    }
    section.add(*(FigureBlock(path, captions[key]) for key, path in paths.items()))
    return section


def _dial_figures(
    outcomes: Sequence[Outcome],
    records: Sequence[RunRecord],
    margins: Sequence,
    settings: str,
    figures: Path,
) -> dict[str, Path]:
    """The hit-rate dial's figure and the γ dial's, each where it has two points or more
    (``records``: the study's matches)."""
    from cmarlcd.reports import figures as figs

    group = sorted({(r.key.algorithm, r.key.config) for r in records})
    seed = records[0].key.root_seed
    names = {n: registry.display_name(n) for n in _order(outcomes)}
    paths = {}
    dial = {dialled(o.reading.readings): o.cells for o in outcomes if o.reading.kind == "hit rate"}
    if len(dial) >= 2:
        title = f"Win rate against each opponent as the hit rate of every unit varies ({settings})"
        stem = figure_name(f"battlefield-hit-rates-seed{seed}", group)
        paths["hit_rates"] = figs.hit_rate_dial(dial, names, title, figures / stem)
    if len({m.gamma for m in margins}) >= 2:
        title = (
            "Margin of each tabular learner against each opponent as the discount γ of "
            f"CMARL-CD and LA-OCA varies ({settings})"
        )
        stem = figure_name(f"battlefield-gamma-seed{seed}", group)
        paths["gamma"] = figs.gamma_dial(margins, names, title, figures / stem)
    return paths


def _pointed_to(outcomes: Sequence[Outcome]) -> study.Reading | None:
    """The reading the study points to (:func:`study.pointed_to`), None when the
    defaults' main claim was not checked."""
    return study.pointed_to({o.reading: o.score for o in outcomes})


def _pointed_text(pointed: study.Reading, outcomes: Sequence[Outcome]) -> str:
    """The reading the study points to, its mean margin beside the dials' best point's
    (a combination may do worse than the point alone), and the command that plays it at
    the paper's full protocol."""
    scores = {o.reading: o.score for o in outcomes}
    best = study.best_dial_point(scores)

    def margin(reading: study.Reading) -> str:
        score = scores.get(reading, math.nan)
        return "not played yet" if math.isnan(score) else f"mean margin {100 * score:+.1f}"

    words = f"{pointed.name} ({margin(pointed)})"
    if pointed != best:
        words += f"; the dials' best point alone: {best.name} ({margin(best)})"
        if scores.get(pointed, math.inf) < scores[best]:
            words += ", so the combination did worse than its point alone"
    command = [
        "cmarl-cd tournament",
        *study.tournament_options(pointed.readings),
        *("--rounds", str(tour.PAPER_ROUNDS)),
        *("--learn-episodes", f"{tour.PAPER_LEARN_EPISODES // 1000}k"),
        *("--eval-episodes", f"{tour.PAPER_EVAL_EPISODES // 1000}k"),
    ]
    return (
        "The reading the study points to (the dials' best point, with every switch that "
        f"raised CMARL-CD's mean margin above the defaults'): {words}. At the paper's "
        f"full protocol: {' '.join(command)}."
    )


def defaults_text() -> str:
    """The default readings in words."""
    d = tour.DEFAULT_READING
    units = ", ".join(
        f"{kind} {d[kind]['hp']} HP / {d[kind]['damage']} damage / hit {d[kind]['hit_rate']:g}"
        for kind in tour.UNIT_KINDS
    )
    return (
        f"γ {d['gamma']:g} and tolerance {d['tolerance']:g} for the tabular learners, the "
        f"{d['unseen']} legal target in unseen states, {units}"
    )


def stored_readings_section(records: Sequence[RunRecord], figures: Path) -> Section:
    """:func:`readings_section` of one study found in the store (its tournaments'
    matches, :func:`cmarlcd.experiments.readings.stored_studies`)."""
    (outcomes,) = stored_studies(match_results.tournaments(records))
    return readings_section(outcomes, figures)


def _order(outcomes: Sequence[Outcome]) -> list[str]:
    present = {c.algorithm for o in outcomes for c in o.cells}
    known = list(tour.battlefield_learners())
    return sorted(present, key=lambda n: (known.index(n) if n in known else len(known), n))
