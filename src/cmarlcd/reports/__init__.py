"""Reports of stored runs, as data first: each experiment's runs become a
:class:`~.section.Section` (title, settings, the versions and count of its runs, tables
whose cells hold our value beside the paper's, notes, claims, figures, its JSON), one
module per experiment's section; the renderers read sections and nothing else (rich text
on a terminal, :mod:`~.render`; Markdown and HTML, :mod:`~.document`; JSON,
:meth:`~.section.Section.document`), and :mod:`~.figures` draws the PNGs.

Above the sweeps and the experiments, below the command line.
"""

from cmarlcd.reports.compare import compare_section
from cmarlcd.reports.dsn import DSN_TABLES, TRAIN_ONCE_NOTE, dsn_section, dsn_tables, protocol_text
from cmarlcd.reports.environment import environment_section
from cmarlcd.reports.readings import readings_section, stored_readings_section
from cmarlcd.reports.repeated import SUCCESS_BAR, games_table, repeated_section, success_table
from cmarlcd.reports.scaling import scaling_section
from cmarlcd.reports.section import (
    Section,
    figure_name,
    new_section,
    percent,
    runs_text,
    versions,
)
from cmarlcd.reports.theorem import theory_section
from cmarlcd.reports.tournament import tournament_section, tournament_tables

__all__ = [
    "DSN_TABLES",
    "SUCCESS_BAR",
    "TRAIN_ONCE_NOTE",
    "Section",
    "compare_section",
    "dsn_section",
    "dsn_tables",
    "environment_section",
    "figure_name",
    "games_table",
    "new_section",
    "percent",
    "protocol_text",
    "readings_section",
    "repeated_section",
    "runs_text",
    "scaling_section",
    "stored_readings_section",
    "success_table",
    "theory_section",
    "tournament_section",
    "tournament_tables",
    "versions",
]
