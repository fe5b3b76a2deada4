"""Check a built documentation site the way a reader would meet it (stdlib only).

``python .ci/check_site.py SITE_DIR`` reads every HTML page of a built site and prints one
line ``page: problem`` for each of:

- a paragraph (or list item) that holds Markdown the converter left as text: a table
  (lines starting with ``|`` and a ``|---|`` separator row), a list, a fenced code block
  or an admonition swallowed by the paragraph before it (no blank line between them);
- an ``<img src>`` that does not resolve to a file in the site, or that loads from the
  network;
- an internal ``<a href>`` (relative or site-absolute) that does not resolve to a page or
  file in the site, or whose ``#fragment`` names no element of the target page;
- a ``<script src>`` or ``<link href>`` that loads from the network (the site must work
  offline), or that does not resolve in the site; and a mermaid diagram, which the theme
  draws with a script fetched from the network.

Exit status: 0 when there is no problem, 1 when there is one, 2 on a usage error.
"""

from __future__ import annotations

import os
import re
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

#: Elements whose text is checked for Markdown left unconverted.
BLOCKS = {"p", "li"}
#: Elements whose text is no reader's text.
SKIPPED = {"script", "style"}
#: ``<link rel>`` values that name a URL without loading it.
NOT_LOADED = {"canonical", "alternate", "author", "license", "me", "help", "search"}

TABLE_ROW = re.compile(r"^\|.*\|")
SEPARATOR = re.compile(r"^\|?\s*:?[-–—]{3,}:?\s*(\|\s*:?[-–—]{3,}:?\s*)*\|?$")
LIST_ITEM = re.compile(r"^([-*+]|\d+\.)\s+\S")
FENCE = re.compile(r"^(```|~~~)")
ADMONITION = re.compile(r"^(!!!|\?\?\?\+?)\s+\w")
INDENTED = re.compile(r"^ {4,}\S")


class Page(HTMLParser):
    """What one page holds: ids, references, and the text of each paragraph."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.references: list[tuple[str, str, str]] = []  # (kind, url, rel)
        self.blocks: list[tuple[str, str]] = []  # (tag, text)
        self.mermaid = 0
        self._open: list[tuple[str, list[str]]] = []
        self._skip = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        attributes = {name: value or "" for name, value in attrs}
        if "id" in attributes:
            self.ids.add(attributes["id"])
        if tag == "a" and "name" in attributes:
            self.ids.add(attributes["name"])
        if "mermaid" in attributes.get("class", "").split():
            self.mermaid += 1
        rel = attributes.get("rel", "")
        if tag == "img" and "src" in attributes:
            self.references.append(("img", attributes["src"], rel))
        elif tag == "a" and "href" in attributes:
            self.references.append(("a", attributes["href"], rel))
        elif tag == "script" and "src" in attributes:
            self.references.append(("script", attributes["src"], rel))
        elif tag == "link" and "href" in attributes:
            self.references.append(("link", attributes["href"], rel))
        if tag in SKIPPED:
            self._skip += 1
        elif tag in BLOCKS:
            if tag == "p":  # a paragraph ends at the next one, closed or not
                self._close("p")
            self._open.append((tag, []))

    def handle_endtag(self, tag: str) -> None:
        if tag in SKIPPED:
            self._skip = max(0, self._skip - 1)
        elif tag in BLOCKS:
            self._close(tag)

    def handle_data(self, data: str) -> None:
        if self._open and not self._skip:
            self._open[-1][1].append(data)

    def close(self) -> None:
        super().close()
        while self._open:
            self._close(self._open[-1][0])

    def _close(self, tag: str) -> None:
        if not any(open_tag == tag for open_tag, _ in self._open):
            return
        while self._open:
            open_tag, parts = self._open.pop()
            self.blocks.append((open_tag, "".join(parts)))
            if open_tag == tag:
                return


def unrendered(tag: str, text: str) -> str | None:
    """What Markdown a paragraph's (or list item's) text holds unconverted, if any."""
    lines = text.splitlines()
    if tag == "li" and lines and lines[0][:1].strip() and any(map(INDENTED.match, lines[1:])):
        # Python-Markdown strips the indentation of a list item's lines (an item written
        # by a template, not by Markdown, starts with white space); what keeps 4 spaces
        # is the item of a nested list indented by less than 4 spaces, flattened
        return "a nested list flattened into its parent (indent nested items by 4 spaces)"
    lines = [line.strip() for line in text.splitlines()]
    lines = [line for line in lines if line]
    rows = [line for line in lines if TABLE_ROW.match(line)]
    if rows and any(SEPARATOR.match(line) and "|" in line for line in lines):
        return f"a table left as a paragraph ({snippet(rows[0])})"
    for line in lines[1:]:
        if LIST_ITEM.match(line):
            return f"a list left in a paragraph ({snippet(line)})"
    for line in lines:
        if FENCE.match(line):
            return f"a fenced code block left in a paragraph ({snippet(line)})"
        if ADMONITION.match(line):
            return f"an admonition left in a paragraph ({snippet(line)})"
    return None


def snippet(line: str, length: int = 60) -> str:
    return repr(line if len(line) <= length else line[: length - 1] + "…")


def off_site(url: str) -> bool:
    split = urlsplit(url)
    return split.scheme in ("http", "https") or (not split.scheme and bool(split.netloc))


class Site:
    def __init__(self, root: Path) -> None:
        self.root = root.resolve()
        self._pages: dict[Path, Page] = {}

    def page(self, path: Path) -> Page:
        if path not in self._pages:
            parser = Page()
            parser.feed(path.read_text(encoding="utf-8", errors="replace"))
            parser.close()
            self._pages[path] = parser
        return self._pages[path]

    def resolve(self, page: Path, url: str) -> tuple[Path | None, str, str | None]:
        """The file a site-internal URL names, its fragment, and why it names none."""
        split = urlsplit(url)
        fragment = unquote(split.fragment)
        path = unquote(split.path)
        if not path:
            return page, fragment, None
        base = self.root if path.startswith("/") else page.parent
        target = Path(os.path.normpath(base / path.lstrip("/")))
        if target != self.root and self.root not in target.parents:
            return None, fragment, "points outside the site"
        if target.is_dir():
            target = target / "index.html"
        if not target.is_file():
            return None, fragment, "names no file in the site"
        return target, fragment, None

    def check(self) -> tuple[int, list[str]]:
        pages = sorted(self.root.rglob("*.html"))
        problems = []
        for path in pages:
            name = path.relative_to(self.root).as_posix()
            problems += [f"{name}: {problem}" for problem in self.check_page(path)]
        return len(pages), problems

    def check_page(self, path: Path) -> list[str]:
        page = self.page(path)
        problems = []
        for tag, text in page.blocks:
            found = unrendered(tag, text)
            if found:
                problems.append(found)
        if page.mermaid:
            problems.append(
                f"{page.mermaid} mermaid diagram(s): drawn by a script loaded from the network"
            )
        for kind, url, rel in page.references:
            scheme = urlsplit(url).scheme
            if kind == "a":
                if scheme or urlsplit(url).netloc:
                    continue  # http(s), mailto and the like: not the site's to check
                target, fragment, why = self.resolve(path, url)
                if why:
                    problems.append(f"link {url!r} {why}")
                elif (
                    fragment and target.suffix == ".html" and fragment not in self.page(target).ids
                ):
                    problems.append(f"link {url!r}: no element with id {fragment!r} there")
                continue
            if scheme == "data":
                continue
            if kind == "link" and NOT_LOADED & set(rel.lower().split()):
                continue
            what = {"img": "image", "script": "script", "link": "stylesheet or link"}[kind]
            if off_site(url):
                problems.append(f"{what} {url!r} loads from the network")
            elif scheme:
                problems.append(f"{what} {url!r} is not a file of the site")
            else:
                _, _, why = self.resolve(path, url)
                if why:
                    problems.append(f"{what} {url!r} {why}")
        return problems


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not Path(argv[0]).is_dir():
        print("usage: check_site.py SITE_DIR (a built site's folder)", file=sys.stderr)
        return 2
    count, problems = Site(Path(argv[0])).check()
    for problem in problems:
        print(problem)
    if problems:
        print(f"check_site: {len(problems)} problem(s) in {count} pages", file=sys.stderr)
        return 1
    print(f"check_site: {count} pages, no problems")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
