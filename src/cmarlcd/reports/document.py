"""Sections (:mod:`cmarlcd.reports.section`) as one self-contained report: Markdown or HTML.

Each section shows what the reader needs to trust it: the settings, the code version(s)
that computed the runs and how many runs there are. The Markdown links its figures; the
HTML page inlines them as base64 PNG, styles inline: it opens with no other file.
"""

from __future__ import annotations

import base64
import html
import os
from collections.abc import Sequence
from pathlib import Path

from cmarlcd.reports.section import Block, FigureBlock, Section, TableBlock

# ------------------------------------------------------------------ Markdown


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", "<br>")


def _md_table(block: TableBlock) -> list[str]:
    lines = [f"**{block.title}**", ""] if block.title else []
    lines.append("| " + " | ".join(_md_cell(c) for c in block.columns) + " |")
    lines.append("|" + "---|" * len(block.columns))
    lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.plain_rows()]
    if block.caption:
        lines += ["", f"*{block.caption}*"]
    return [*lines, ""]


def render_markdown(
    title: str, preamble: Sequence[str], sections: Sequence[Section], output: Path | None
) -> str:
    """The report as Markdown; figures are linked relative to ``output``'s folder."""
    base = Path.cwd() if output is None else Path(output).resolve().parent
    lines = [f"# {title}", "", *[f"{line}  " for line in preamble], ""]
    for section in sections:
        lines += [f"## {section.title}", "", f"{section.settings}. {section.facts()}.", ""]
        warning = section.warning()
        if warning is not None:
            lines += [f"> **{warning}**", ""]
        for block in section.blocks:
            if isinstance(block, TableBlock):
                lines += _md_table(block)
            elif isinstance(block, FigureBlock):
                link = os.path.relpath(block.path.resolve(), base)
                lines += [f"![{block.caption}]({link})", "", f"*{block.caption}*", ""]
            elif block.warning:
                lines += [f"> **{block.text}**", ""]
            else:
                lines += [f"- {block.text}" if block.item else block.text, ""]
    return "\n".join(lines)


# ---------------------------------------------------------------------- HTML

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 70rem; margin: 2rem auto;
       padding: 0 1rem; color: #222; line-height: 1.45; }
h1 { font-size: 1.6rem; } h2 { font-size: 1.25rem; margin-top: 2.5rem;
       border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5rem 0 0.2rem; font-size: 0.9rem; }
th, td { border: 1px solid #bbb; padding: 0.25rem 0.5rem; text-align: right;
         vertical-align: top; }
th:first-child, td:first-child { text-align: left; }
caption { caption-side: top; font-weight: 600; text-align: left; padding: 0.3rem 0; }
.note { color: #555; font-size: 0.9rem; }
.facts { color: #444; }
.warning { color: #a40000; font-weight: 600; }
figure { margin: 1rem 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { color: #555; font-size: 0.9rem; }
"""


def _html_text(text: str) -> str:
    return html.escape(text).replace("\n", "<br>")


def _html_table(block: TableBlock) -> str:
    head = "".join(f"<th>{_html_text(c)}</th>" for c in block.columns)
    body = "".join(
        "<tr>" + "".join(f"<td>{_html_text(c)}</td>" for c in row) + "</tr>"
        for row in block.plain_rows()
    )
    caption = f"<caption>{_html_text(block.title)}</caption>" if block.title else ""
    note = f'<p class="note">{_html_text(block.caption)}</p>' if block.caption else ""
    return f"<table>{caption}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>{note}"


def _html_figure(block: FigureBlock) -> str:
    data = base64.b64encode(block.path.read_bytes()).decode("ascii")
    caption = _html_text(block.caption)
    return (
        f'<figure><img alt="{caption}" src="data:image/png;base64,{data}">'
        f"<figcaption>{caption}</figcaption></figure>"
    )


def _html_block(block: Block) -> str:
    if isinstance(block, TableBlock):
        return _html_table(block)
    if isinstance(block, FigureBlock):
        return _html_figure(block)
    css = "warning" if block.warning else "text"
    text = f"• {block.text}" if block.item else block.text
    return f'<p class="{css}">{_html_text(text)}</p>'


def render_html(title: str, preamble: Sequence[str], sections: Sequence[Section]) -> str:
    """The report as one HTML page with every figure inlined."""
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        *[f'<p class="facts">{_html_text(line)}</p>' for line in preamble],
    ]
    for section in sections:
        parts.append(f"<h2>{html.escape(section.title)}</h2>")
        parts.append(
            f'<p class="facts">{_html_text(section.settings)}. {_html_text(section.facts())}.</p>'
        )
        warning = section.warning()
        if warning is not None:
            parts.append(f'<p class="warning">{_html_text(warning)}</p>')
        parts += [_html_block(block) for block in section.blocks]
    parts.append("</body></html>")
    return "\n".join(parts)
