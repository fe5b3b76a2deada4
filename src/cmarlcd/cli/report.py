"""``cmarl-cd report``: every table and figure from the results store, in one of four
formats (computes nothing)."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from cmarlcd import provenance, reports
from cmarlcd.cli.app import app
from cmarlcd.cli.options import (
    DEFAULT_FIGURES,
    FiguresOption,
    StoreOption,
    check_outputs,
    fails_cleanly,
)
from cmarlcd.cli.theory import theorem_sections
from cmarlcd.errors import require
from cmarlcd.experiments import compare as cmp
from cmarlcd.experiments import environment as envs
from cmarlcd.experiments import episodic_results, games, scaling, theorem
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import sensor_network as dsn_exp
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments import tournament_results as match_results
from cmarlcd.reports.compare import compare_section
from cmarlcd.reports.environment import environment_section
from cmarlcd.reports.environment import protocol_key as env_key
from cmarlcd.reports.game_training import game_training_section
from cmarlcd.reports.render import say, show_section
from cmarlcd.reports.scaling import scaling_section
from cmarlcd.reports.section import Section, version_warning
from cmarlcd.sweeps.store import DEFAULT_STORE, ResultStore, RunRecord
from cmarlcd.version import __version__

FORMATS = ("text", "markdown", "html", "json")


@app.command("report")
@fails_cleanly
def report_command(
    case: Annotated[
        int | None, typer.Option(help="Only Table 1 or 2 of this case.", show_default=False)
    ] = None,
    seed: Annotated[
        int | None, typer.Option(help="Only sweeps with this root seed.", show_default=False)
    ] = None,
    output_format: Annotated[
        str,
        typer.Option(
            "--format",
            help="text: tables on the terminal; markdown; html: one self-contained page "
            "(figures inlined); json.",
        ),
    ] = "text",
    output: Annotated[
        Path | None,
        typer.Option(help="Write the report to this file [default: stdout].", show_default=False),
    ] = None,
    store: StoreOption = DEFAULT_STORE,
    figures: FiguresOption = DEFAULT_FIGURES,
    as_json: Annotated[
        bool, typer.Option("--json", help="Same as --format json.", show_default=False)
    ] = False,
) -> None:
    """Render every table and figure from the results store, beside the paper's values,
    with the settings, code version and run count of each group (computes nothing)."""
    require(case in (None, 1, 2), "case", f"must be 1 or 2 (got {case})")
    output_format = "json" if as_json else output_format
    require(
        output_format in FORMATS,
        "format",
        f"must be one of {', '.join(FORMATS)} (got {output_format!r})",
    )
    if output is not None:
        require(not output.is_dir(), "output", f"{output} is a directory, not a file")
        check_outputs(figures=output.parent)
    with ResultStore(store, create=False) as db:
        check_outputs(figures=figures)
        groups = _report_groups(db, case, seed)
        where = db.provenances()
    if output_format == "text":
        _text_report(groups, store, figures)
        for line in provenance.store_lines(where) if groups else []:
            print(line)
        return
    text = _document(groups, output_format, store, figures, output, where)
    if output is None:
        print(text)
    else:
        output.parent.mkdir(parents=True, exist_ok=True)
        output.write_text(text + "\n", encoding="utf-8")
        print(f"report: {output} ({len(groups)} sections from {store})", file=sys.stderr)


#: Makes the section of one stored group of runs, drawing its figures into a folder.
Renderer = Callable[[Sequence[RunRecord], Path], Section]


def _report_groups(
    db: ResultStore, case: int | None, seed: int | None
) -> list[tuple[str, Renderer, list[RunRecord]]]:
    """The stored groups of runs the filters keep, in the paper's order: (kind, renderer,
    records)."""

    def dsn(records: Sequence[RunRecord], figures: Path) -> Section:
        return reports.dsn_section(dsn_exp.DSN_GAME, records, figures)

    found: list[tuple[str, Renderer, list[RunRecord]]] = []
    for records in rep.stored_tables(db.records(rep.EXPERIMENT)).values():
        if case in (None, rep.cell_of(records[0]).case):
            found.append(("repeated", reports.repeated_section, records))
    if case is None:
        kinds = (
            ("dsn", dsn, dsn_exp.EXPERIMENT, episodic_results.protocol_key),
            ("theorem1", _theorem_section, theorem.EXPERIMENT, _theorem_key),
        )
        dsn_runs = [r for r in db.records(dsn_exp.EXPERIMENT) if cmp.is_comparison_dsn_run(r)]
        compared = {r.key for r in dsn_runs}  # reported with the comparison
        for kind, render, experiment, key in kinds:
            stored = (r for r in db.records(experiment) if r.key not in compared)
            for records in _groups(stored, key).values():
                found.append((kind, render, records))
            if kind == "dsn":  # the paper's order: DSN, battlefield, Theorem 1
                found += _battlefield_groups(db.records(tour.EXPERIMENT))
        for seed_, records in _groups(db.records(cmp.EXPERIMENT), _seed_key).items():
            ours = [r for r in dsn_runs if r.key.root_seed == seed_]
            found.append(("compare", compare_section, records + ours))
        for records in _groups(db.records(scaling.EXPERIMENT), scaling.protocol_key).values():
            found.append(("scaling", scaling_section, records))
        for records in _groups(db.records(envs.EXPERIMENT), env_key).values():
            found.append(("train", environment_section, records))
        for family in games.FAMILIES.values():  # train --game
            for records in _groups(db.records(family.name), _game_key).values():
                found.append(("train", _game_section, records))
    return [g for g in found if seed in (None, g[2][0].key.root_seed)]


def _battlefield_groups(records: list[RunRecord]) -> list[tuple[str, Renderer, list[RunRecord]]]:
    """Each stored tournament, then each readings study (two or more readings with the
    same seed and budgets) as one more section."""
    from cmarlcd.experiments.readings import stored_studies
    from cmarlcd.reports.readings import stored_readings_section

    groups = match_results.tournaments(records)
    found: list[tuple[str, Renderer, list[RunRecord]]] = [
        ("tournament", reports.tournament_section, g) for g in groups
    ]
    for study in stored_studies(groups):
        every = list({rec.key: rec for o in study for rec in o.records}.values())
        found.append(("readings", stored_readings_section, every))
    return found


def _game_key(rec: RunRecord) -> tuple:
    """Runs of one study on a compiled game: same task, seed, evaluation and budget."""
    settings = episodic_results.run_of(rec)
    return (*episodic_results.protocol_key(rec), str(settings.checkpoints), settings.unit)


def _game_section(records: Sequence[RunRecord], figures: Path) -> Section:
    return game_training_section(records, figures, records[0].key.root_seed)


def _seed_key(rec: RunRecord) -> int:
    return rec.key.root_seed


def _theorem_key(rec: RunRecord) -> tuple[str, int]:
    return rec.key.config, rec.key.root_seed


def _theorem_section(records: Sequence[RunRecord], figures: Path) -> Section:
    (section,) = theorem_sections(records, figures)
    return section


def _sections(
    groups: list[tuple[str, Renderer, list[RunRecord]]], figures: Path
) -> list[tuple[str, Section]]:
    return [(kind, render(records, figures)) for kind, render, records in groups]


def _text_report(
    groups: list[tuple[str, Renderer, list[RunRecord]]], store: Path, figures: Path
) -> None:
    console = Console()
    for _, section in _sections(groups, figures):
        show_section(console, section)
    if not groups:
        print(f"the store {store} holds no finished runs matching the filters")
    else:
        say(console, f"results: read from {store}, figures in {figures}/")


def _document(
    groups: list[tuple[str, Renderer, list[RunRecord]]],
    output_format: str,
    store: Path,
    figures: Path,
    output: Path | None,
    where: list[tuple[dict[str, Any] | None, int]],
) -> str:
    """The whole report in one format other than text."""
    from collections import Counter

    from cmarlcd.reports import document

    sections = _sections(groups, figures)
    docs: dict[str, list] = {
        kind: []
        for kind in (
            "repeated",
            "dsn",
            "tournament",
            "readings",
            "theorem1",
            "compare",
            "scaling",
            "train",
        )
    }
    for kind, section in sections:
        docs[kind].append({**section.document(), "runs": section.runs})
    unique = {rec.key: rec for _, _, records in groups for rec in records}  # a run may
    every = Counter(rec.version for rec in unique.values())  # be in two sections
    preamble = [
        f"Results store: {store} ({len(unique)} runs in "
        f"{len(sections)} groups); rendered by cmarl-cd {__version__}.",
        "Our numbers come first; the paper's, where it reports them for the same "
        "settings, follow in brackets.",
    ]
    warning = version_warning(every)
    if warning is not None:
        preamble.append(warning)
    preamble += provenance.store_lines(where)
    title = "CMARL-CD: reproduction report"
    if output_format == "json":
        computed = {"provenance": provenance.as_json(where)}
        return json.dumps({"store": str(store), "versions": dict(every), **computed, **docs},
                          indent=2)  # fmt: skip
    only = [section for _, section in sections]
    if output_format == "markdown":
        return document.render_markdown(title, preamble, only, output)
    return document.render_html(title, preamble, only)


def _groups(records: Iterable[Any], key: Callable[[Any], Any]) -> dict[Any, list]:
    groups: dict[Any, list] = {}
    for rec in records:
        groups.setdefault(key(rec), []).append(rec)
    return groups
