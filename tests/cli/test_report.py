"""The ``report`` command end to end: every section in every format, a page that opens
on its own, mixed versions, and output it cannot write."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cmarlcd import __version__
from cmarlcd.sweeps.store import ResultStore
from tests.cli.common import (
    SECTIONS,
    invoke,
    small_repeated,
    tiny_reproduction,
)


@pytest.mark.slow
def test_report_renders_every_section_in_every_format(paths, monkeypatch, tmp_path) -> None:
    store, _, where = paths
    tiny_reproduction(paths, monkeypatch)
    markdown = tmp_path / "out" / "report.md"
    result = invoke("report", *where, "--format", "markdown", "--output", str(markdown))
    assert result.exit_code == 0, result.output
    text = markdown.read_text()
    for section in SECTIONS:
        assert f"## {section}" in text
    assert "(100)" in text  # the paper's value beside ours (Table 1: 100 %)
    assert f"computed by cmarl-cd {__version__}" in text
    assert "1 stored run" in text and "runs per cell" in text
    for link in [line.split("](")[1][:-1] for line in text.splitlines() if line.startswith("![")]:
        assert (markdown.parent / link).is_file(), link  # figures linked from the file's folder
    html = invoke("report", *where, "--format", "html")
    assert html.exit_code == 0
    for section in SECTIONS:
        assert f"<h2>{section}" in html.stdout
    doc = json.loads(invoke("report", *where, "--format", "json").stdout)
    assert {len(doc[k]) for k in ("repeated", "dsn", "tournament", "theorem1", "compare")} >= {1}
    assert doc["versions"] == {__version__: sum(1 for _ in ResultStore(store).records())}


@pytest.mark.slow
def test_the_html_report_opens_with_no_other_file(paths, monkeypatch, tmp_path) -> None:
    import re

    tiny_reproduction(paths, monkeypatch)
    page = tmp_path / "report.html"
    assert invoke("report", *paths[2], "--format", "html", "--output", str(page)).exit_code == 0
    html = page.read_text()
    sources = re.findall(r'(?:src|href)="([^"]*)"', html)
    assert sources and all(s.startswith("data:image/png;base64,") for s in sources)
    assert "<link" not in html and "<script" not in html and "url(" not in html
    figures = sorted(paths[1].glob("*.png"))
    assert len(sources) == len(figures)  # every figure drawn is in the page


def test_a_report_that_mixes_versions_says_so(paths) -> None:
    store, _, where = paths
    assert small_repeated(where).exit_code == 0
    with ResultStore(store) as db:
        db._conn.execute("UPDATE runs SET version = '0.0.1' WHERE run_index = 0")
    text = invoke("report", *where)
    assert "mix package versions (0.0.1, " in " ".join(text.stdout.split())
    markdown = invoke("report", *where, "--format", "markdown").stdout
    assert "mix package versions" in markdown and "0.0.1 (2 runs)" in markdown


@pytest.mark.parametrize(
    ("args", "option"),
    [(["--format", "pdf"], "--format"), (["--output", "."], "--output")],
)
def test_report_bad_format_or_output(paths, args, option) -> None:
    _, _, where = paths
    assert small_repeated(where).exit_code == 0
    result = invoke("report", *where, *args)
    assert result.exit_code == 2 and result.stderr.startswith(f"error: {option}:")


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
def test_a_report_that_cannot_be_written_is_one_line(paths) -> None:
    """/proc takes no new file, even from root (for whom os.access says it could)."""
    _, _, where = paths
    assert small_repeated(where).exit_code == 0
    result = invoke("report", *where, "--format", "html", "--output", "/proc/report.html")
    assert result.exit_code == 2
    assert result.stderr.startswith("error:") and "/proc" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
