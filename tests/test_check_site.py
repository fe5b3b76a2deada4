"""The built-site checker of CI (.ci/check_site.py), on tiny hand-written sites."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

CHECKER = Path(__file__).resolve().parents[1] / ".ci" / "check_site.py"
spec = importlib.util.spec_from_file_location("check_site", CHECKER)
check_site = importlib.util.module_from_spec(spec)
spec.loader.exec_module(check_site)

HEAD = (
    '<head><link rel="stylesheet" href="{up}assets/main.css">'
    '<script src="{up}assets/bundle.js"></script></head>'
)
TABLE = (
    "<table><thead><tr><th>a</th><th>b</th></tr></thead>"
    "<tbody><tr><td>1</td><td>2</td></tr></tbody></table>"
)


def page(body: str, up: str = "", head: str = HEAD) -> str:
    return f"<!doctype html><html>{head.format(up=up)}<body>{body}</body></html>"


@pytest.fixture
def site(tmp_path: Path) -> Path:
    """A clean site: two pages, an image, the theme's assets."""
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "main.css").write_text("body {}")
    (tmp_path / "assets" / "bundle.js").write_text("")
    (tmp_path / "figure.png").write_bytes(b"\x89PNG")
    (tmp_path / "index.html").write_text(
        page(
            '<h1 id="home">Home</h1><p>See <a href="guide/#usage">the guide</a>, '
            '<a href="/guide/">the same</a>, <a href="#home">the top</a>, '
            '<a href="https://example.org/x">a site</a> and <a href="mailto:a@b.c">us</a>.</p>'
            f'{TABLE}<p><img src="figure.png" alt="a figure"></p>'
            "<ul><li>one item\n  continued</li><li>two</li></ul>"
            "<p>A paragraph may hold a | pipe,\n| start a line with one, or -- dashes.</p>"
        )
    )
    (tmp_path / "guide").mkdir()
    (tmp_path / "guide" / "index.html").write_text(
        page(
            '<h2 id="usage">Usage</h2><p><img src="../figure.png" alt=""></p>'
            "<pre><code>| a | b |\n|---|---|\n| 1 | 2 |\n</code></pre>",
            up="../",
        )
    )
    return tmp_path


def problems(site: Path) -> list[str]:
    return check_site.Site(site).check()[1]


def add_page(site: Path, body: str, head: str = HEAD) -> None:
    (site / "extra.html").write_text(page(body, head=head))


def test_a_clean_site_passes(site, capsys):
    assert problems(site) == []
    assert check_site.main([str(site)]) == 0
    assert "2 pages, no problems" in capsys.readouterr().out


def test_a_table_left_as_a_paragraph(site):
    add_page(
        site,
        "<p>The claims:\n| the paper says | ours |\n|---|---|\n| A beats B | supported |</p>",
    )
    found = problems(site)
    assert len(found) == 1
    assert found[0].startswith("extra.html: a table left as a paragraph")
    assert "the paper says" in found[0]


def test_a_table_with_aligned_separators_in_a_list_item(site):
    add_page(site, "<ul><li>Results:\n| a | b |\n| :--- | ---: |\n| 1 | 2 |</li></ul>")
    found = problems(site)
    assert len(found) == 1
    assert found[0].startswith("extra.html: a table left as a paragraph ('| a | b |')")


def test_other_markdown_left_as_text(site):
    add_page(
        site,
        "<p>Causes:\n- one\n- two</p>"
        "<p>Run it:\n```bash\ncmarl-cd play\n```</p>"
        "<p>Beware.\n!!! warning\n    slow</p>"
        "<ul><li>A parent.</li>"
        "<li>A flattened child that goes on\n    on a line of its own.</li></ul>",
    )
    found = sorted(problems(site))
    assert len(found) == 4
    assert any("a list left in a paragraph" in p for p in found)
    assert any("a fenced code block left in a paragraph" in p for p in found)
    assert any("an admonition left in a paragraph" in p for p in found)
    assert any("a nested list flattened into its parent" in p for p in found)


def test_an_image_that_is_not_in_the_site(site):
    add_page(site, '<p><img src="missing.png"><img src="https://example.org/a.png"></p>')
    assert problems(site) == [
        "extra.html: image 'missing.png' names no file in the site",
        "extra.html: image 'https://example.org/a.png' loads from the network",
    ]


def test_links_to_missing_pages_and_anchors(site):
    add_page(
        site,
        '<p><a href="nowhere/">a</a> <a href="guide/#no-such-heading">b</a> '
        '<a href="#nor-here">c</a> <a href="../../etc/passwd">d</a> '
        '<a href="/guide/#usage">fine</a> <a href="guide/index.html">fine</a></p>',
    )
    assert problems(site) == [
        "extra.html: link 'nowhere/' names no file in the site",
        "extra.html: link 'guide/#no-such-heading': no element with id 'no-such-heading' there",
        "extra.html: link '#nor-here': no element with id 'nor-here' there",
        "extra.html: link '../../etc/passwd' points outside the site",
    ]


def test_scripts_and_stylesheets_from_the_network(site):
    head = (
        '<head><link rel="stylesheet" href="https://fonts.googleapis.com/css?family=Roboto">'
        '<link rel="preconnect" href="https://fonts.gstatic.com">'
        '<link rel="canonical" href="https://example.org/extra/">'
        '<script src="//unpkg.com/mermaid.min.js"></script>'
        '<script src="assets/gone.js"></script></head>'
    )
    add_page(site, '<pre class="mermaid"><code>flowchart TD\n a --> b</code></pre>', head=head)
    assert problems(site) == [
        "extra.html: 1 mermaid diagram(s): drawn by a script loaded from the network",
        "extra.html: stylesheet or link 'https://fonts.googleapis.com/css?family=Roboto' "
        "loads from the network",
        "extra.html: stylesheet or link 'https://fonts.gstatic.com' loads from the network",
        "extra.html: script '//unpkg.com/mermaid.min.js' loads from the network",
        "extra.html: script 'assets/gone.js' names no file in the site",
    ]


def test_main_lists_each_problem_and_fails(site, capsys):
    add_page(site, '<p><img src="missing.png"></p>')
    assert check_site.main([str(site)]) == 1
    captured = capsys.readouterr()
    assert captured.out == "extra.html: image 'missing.png' names no file in the site\n"
    assert "1 problem(s) in 3 pages" in captured.err


def test_main_refuses_a_folder_that_is_not_there(tmp_path, capsys):
    assert check_site.main([str(tmp_path / "nowhere")]) == 2
    assert "usage" in capsys.readouterr().err
