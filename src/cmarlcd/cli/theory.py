"""``cmarl-cd theory``: Theorem 1 numerically; the Theorem 1 sections of the report."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import reports
from cmarlcd import theory as theory_module
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    DEFAULT_FIGURES,
    FiguresOption,
    JsonOption,
    check_outputs,
    fails_cleanly,
)
from cmarlcd.reports.render import say, show_section
from cmarlcd.reports.section import Section
from cmarlcd.sweeps.store import RunRecord


@app.command()
@fails_cleanly
def theory(
    agents: Annotated[int, typer.Option(help="Agents n.")] = 2,
    optima: Annotated[int, typer.Option(help="Optimal joint actions m (unique components).")] = 2,
    temperature: Annotated[float, typer.Option(help="T of eq. (5).")] = 1.0,
    starts: Annotated[
        int, typer.Option(help="Random interior starting points.")
    ] = theory_module.DEFAULT_STARTS,
    seed: Annotated[int, typer.Option(help="Seed of the starting points.")] = 0,
    as_json: JsonOption = False,
    figures: FiguresOption = DEFAULT_FIGURES,
) -> None:
    """Theorem 1: integrate the mean-field ODE (8) and check the Jacobian (13) is -(2/T)·I."""
    from cmarlcd.reports.figures import phase_portrait
    from cmarlcd.theory import check_theorem1

    check_outputs(figures=figures)
    result = check_theorem1(agents, optima, temperature, starts=starts, seed=seed)
    doc = result.to_dict()
    if agents == 2 and optima == 2:  # the portrait is of this case only
        path = figures / f"theorem1-phase-T{temperature:g}.png"
        doc["figure"] = str(phase_portrait(path, temperature=temperature, seed=seed))
    if as_json:
        print(json.dumps(doc, indent=2))
        return
    console = Console()
    section = reports.theory_section(doc)
    say(console, f"{section.title}, T = {temperature:g}", "bold")
    show_section(console, section, title=False)


def theorem_sections(records: Sequence[RunRecord], figures: Path) -> list[Section]:
    """The stored Theorem 1 checks, with the phase portrait beside the 2-agent one."""
    from cmarlcd.reports.figures import phase_portrait

    sections = []
    for rec in records:
        doc = dict(rec.metrics)
        if (doc["n_agents"], doc["n_optima"]) == (2, 2):
            path = figures / f"theorem1-phase-T{doc['temperature']:g}.png"
            doc["figure"] = str(phase_portrait(path, doc["temperature"], rec.key.root_seed))
        sections.append(reports.theory_section(doc, [rec]))
    return sections


def theorem_documents(
    records: Sequence[RunRecord], figures: Path, console: Console | None
) -> list[dict[str, Any]]:
    """The stored Theorem 1 checks as JSON documents (shown on ``console`` if any)."""
    docs = []
    for section in theorem_sections(records, figures):
        if console is not None:
            show_section(console, section)
        docs.append(section.data)
    return docs
