"""The report's rendered numbers are its JSON's: every cell of Tables 1-7 and Figs. 6-7 in
the Markdown report, read back, equals the JSON report's value to the printed precision."""

from __future__ import annotations

import json
import re

import pytest
from typer.testing import CliRunner

from cmarlcd.cli import app

TINY_MATCHES = ["--learn-episodes", "60", "--eval-episodes", "60"]
NUMBER = re.compile(r"-?\d[\d,]*(?:\.\d+)?")


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """A small store of every tabular experiment, and its Markdown and JSON reports."""
    folder = tmp_path_factory.mktemp("report")
    where = ["--store", str(folder / "s.sqlite"), "--figures", str(folder / "figures")]
    runner = CliRunner()
    for args in (
        ["repeated", "--agents", "2-3", "--actions", "2-3", "--runs", "3"],
        ["repeated", "--case", "2", "--agents", "4", "--actions", "3", "--runs", "2"],
        ["dsn", "--episodes", "300,600", "--runs", "3", "--eval-episodes", "200"],
        ["tournament", "--algorithms", "cmarl-cd,la-oca", "--rounds", "3", *TINY_MATCHES],
    ):
        done = runner.invoke(app, [*args, "--workers", "1", "--no-progress", *where])
        assert done.exit_code == 0, done.output
    markdown = runner.invoke(app, ["report", "--format", "markdown", *where])
    document = runner.invoke(app, ["report", "--format", "json", *where])
    assert markdown.exit_code == 0 and document.exit_code == 0
    return markdown.stdout, json.loads(document.stdout)


def tables(markdown: str) -> dict[str, list[list[str]]]:
    """Every table of the Markdown report by its bold title: rows of cells (header first)."""
    found: dict[str, list[list[str]]] = {}
    title = None
    for line in markdown.splitlines():
        if line.startswith("**") and line.endswith("**"):
            title = line.strip("*")
        elif line.startswith("|") and title is not None and not line.startswith("|---"):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
            found.setdefault(title, []).append(cells)
    return found


def cell(table: list[list[str]], row: str, column: str) -> str:
    header = table[0]
    (line,) = [r for r in table[1:] if r[0] == row]
    return line[header.index(column)]


def numbers(text: str) -> list[float]:
    return [float(n.replace(",", "")) for n in NUMBER.findall(text)]


def assert_printed(printed: float, text: str, value: float) -> None:
    """``printed`` (a number as ``text`` shows it) is ``value`` rounded to its digits."""
    decimals = len(text.split(".")[1]) if "." in text else 0
    assert abs(printed - value) <= 0.5 * 10.0**-decimals + 1e-9, (text, value)


def check_cell(text: str, values: list[float]) -> None:
    found = NUMBER.findall(text)
    assert len(found) >= len(values), (text, values)
    for raw, value in zip(found, values, strict=False):
        assert_printed(float(raw.replace(",", "")), raw, value)


def titled(found: dict[str, list[list[str]]], start: str) -> list[list[str]]:
    (title,) = [t for t in found if t.startswith(start)]
    return found[title]


@pytest.mark.slow
def test_tables_1_and_2_print_the_json(reports) -> None:
    markdown, document = reports
    found = tables(markdown)
    for group in document["repeated"]:
        case = group["case"]
        success = titled(found, f"Table {case} — success rate")
        games = [found[t] for t in found if t.startswith("Median games") and f"case {case}" in t]
        assert len(games) == 1
        for c in group["cells"]:
            row, column = f"m={c['actions']}", f"n={c['agents']}"
            check_cell(cell(success, row, column).split("(")[0], [100 * c["success_rate"]])
            check_cell(cell(games[0], row, column), [c["median_games"]])


#: The paper's Tables 3-7 and the JSON fields each shows (percent for the success rate).
DSN_TABLES = {
    "Table 3.": [("success_rate", 100)],
    "Table 4.": [("mean_return", 1), ("std_return", 1)],
    "Table 5.": [("mean_steps", 1), ("std_steps", 1)],
    "Table 6.": [("min_return", 1)],
    "Table 7.": [("max_steps", 1)],
}


@pytest.mark.slow
def test_tables_3_to_7_print_the_json(reports) -> None:
    markdown, document = reports
    found = tables(markdown)
    (group,) = document["dsn"]
    for start, fields in DSN_TABLES.items():
        table = titled(found, start)
        for row in group["rows"]:
            text = cell(table, row["label"], f"L = {row['episodes']:,}")
            ours, _, paper = text.partition("<br>")
            check_cell(ours, [scale * row[name] for name, scale in fields])
            if paper:  # the paper's values, in brackets
                check_cell(paper, [scale * row["paper"][name] for name, scale in fields])


@pytest.mark.slow
def test_figs_6_and_7_print_the_json(reports) -> None:
    markdown, document = reports
    found = tables(markdown)
    (group,) = document["tournament"]
    rates, steps = titled(found, "Fig. 6"), titled(found, "Fig. 7")
    names = {"cmarl-cd": "CMARL-CD", "la-oca": "LA-OCA"}
    for c in group["cells"]:
        row, column = names[c["algorithm"]], f"vs {names[c['opponent']]}"
        check_cell(
            cell(rates, row, column),
            [100 * c[k] for k in ("win_rate", "win_rate_std", "loss_rate", "tie_rate")],
        )
        check_cell(cell(steps, row, column), [c["win_steps"], c["win_steps_std"]])
