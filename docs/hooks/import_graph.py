"""The architecture page's diagram, drawn at build time from the package's imports.

A mkdocs hook (``hooks:`` in mkdocs.yml), standard library only. It parses every module
of ``src/cmarlcd`` with :mod:`ast`, groups the modules by top-level module or subpackage
(``registry.py`` is one group, ``training/`` with all its modules another; the learners,
grouped by kind, are split by :data:`SUBGROUPS`), and draws one
box per group in the rows of :data:`LAYERS`, with an arrow from each group to every group
it imports. An import that points up the layers is drawn in red and listed under the
diagram. The picture is written into the built site as an SVG (no script, nothing fetched
at view time), and the architecture page's ``<!-- import-graph -->`` marker becomes the
picture and its notes.

Because the boxes and arrows come from the code, a moved or new module moves the
diagram with it: a group that no layer names is drawn in a last row of its own, and a
name in :data:`LAYERS` that the code no longer has is skipped.

``python docs/hooks/import_graph.py > graph.svg`` draws the picture without mkdocs.
"""

from __future__ import annotations

import ast
import html
import logging
import sys
from bisect import bisect_right, insort
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path

PACKAGE = "cmarlcd"
#: The package's source, relative to mkdocs.yml.
SOURCE = Path("src") / PACKAGE
PAGE = "architecture.md"
MARKER = "<!-- import-graph -->"
IMAGE = "architecture-imports.svg"
#: The group of the package's own ``__init__.py``.
ROOT = "__init__"

#: Groups finer than a top-level subpackage: a file whose path (relative to the package)
#: starts with a key is in that key's group, the longest key that matches winning. The
#: learners are split by kind: the tabular learners and the deep ones import nothing of
#: each other; the fused step imports nothing of the deep learners that call it; the
#: rules both kinds share (the package's own modules) import neither; and the package's
#: ``__init__`` (its public names) stands above them all.
SUBGROUPS: dict[str, str] = {
    "learners/__init__.py": "learners",
    "learners/": "learners/shared",
    "learners/tabular/": "learners/tabular",
    "learners/deep/": "learners/deep",
    "learners/deep/fused/": "learners/deep/fused",
}
#: How a group of :data:`SUBGROUPS` is labelled where its name is no folder of the code.
SUBGROUP_LABELS = {"learners": "learners/__init__", "learners/shared": "learners/*.py"}

#: The layers, top to bottom, each a title and the groups in it: a group may import groups
#: of its own layer and of the layers below. A group is a top-level module (without
#: ``.py``) or subpackage of the package; names the code does not have are skipped.
LAYERS: list[tuple[str, list[str]]] = [
    ("entry points", [ROOT, "__main__"]),
    ("command line", ["cli"]),
    ("reports", ["reports"]),
    ("sweeps", ["sweeps"]),
    ("experiments", ["experiments", "testing"]),
    ("registry", ["registry"]),
    ("training", ["training", "policies"]),
    ("learners, games", ["learners", "learners/tabular", "learners/deep", "games"]),
    ("the learners' parts", ["learners/deep/fused", "learners/shared"]),
    (
        "foundations",
        [
            "runs",
            "theory",
            "progress",
            "run_logs",
            "provenance",
            "limits",
            "devices",
            "compiled",
            "paper",
            "version",
        ],
    ),
    ("leaves", ["errors", "plugins", "_moved"]),
]
UNLAYERED = "in no layer"

log = logging.getLogger(f"mkdocs.hooks.{Path(__file__).stem}")


# --- the graph -------------------------------------------------------------------------


@dataclass
class Group:
    name: str
    package: bool
    modules: list[str] = field(default_factory=list)  # files, relative to the package

    @property
    def label(self) -> str:
        if self.name in SUBGROUP_LABELS:
            return SUBGROUP_LABELS[self.name]
        return f"{self.name}/" if self.package else self.name


@dataclass
class Edge:
    source: str
    target: str
    #: (importing file, imported file, "module" | "function" | "typing")
    imports: list[tuple[str, str, str]] = field(default_factory=list)

    @property
    def kind(self) -> str:
        kinds = {kind for _, _, kind in self.imports}
        return next(kind for kind in ("module", "function", "typing") if kind in kinds)


@dataclass
class Graph:
    groups: dict[str, Group]
    edges: dict[tuple[str, str], Edge]
    layers: list[tuple[str, list[str]]]  # only the groups the code has, and no empty layer

    def layer(self, group: str) -> int:
        return next(i for i, (_, names) in enumerate(self.layers) if group in names)

    def points_up(self, edge: Edge) -> bool:
        """Whether the edge goes from a layer to one above it (a group in no layer: never)."""
        if UNLAYERED in (self.layer_title(edge.source), self.layer_title(edge.target)):
            return False
        return self.layer(edge.target) < self.layer(edge.source)

    def layer_title(self, group: str) -> str:
        return self.layers[self.layer(group)][0]


def build_graph(source: Path, layers: list[tuple[str, list[str]]] = LAYERS) -> Graph:
    """Every group of the package under ``source`` and the imports between groups."""
    modules: dict[str, str] = {}  # dotted name -> file, relative to the package
    groups: dict[str, Group] = {}
    for path in sorted(source.rglob("*.py")):
        relative = path.relative_to(source)
        if any(part.startswith(".") or part == "__pycache__" for part in relative.parts):
            continue
        parts = [PACKAGE, *relative.with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = relative.as_posix()
        name = group_of_file(relative)
        group = groups.setdefault(name, Group(name, package=len(relative.parts) > 1))
        group.modules.append(relative.as_posix())

    def group_of(module: str) -> str:
        return group_of_file(Path(modules[module]))

    edges: dict[tuple[str, str], Edge] = {}
    for module, file in modules.items():
        try:
            tree = ast.parse((source / file).read_text(encoding="utf-8"), filename=file)
        except (SyntaxError, UnicodeDecodeError) as error:
            log.warning(
                "import graph: %s does not parse (%s): drawn without its imports", file, error
            )
            continue
        package = module if file.endswith("__init__.py") else module.rpartition(".")[0]
        for imported, kind in imports_of(tree, package):
            while imported not in modules and "." in imported:
                imported = imported.rpartition(".")[0]
            if imported not in modules:
                continue
            source_group, target_group = group_of(module), group_of(imported)
            if source_group != target_group:
                edge = edges.setdefault(
                    (source_group, target_group), Edge(source_group, target_group)
                )
                edge.imports.append((file, modules[imported], kind))

    placed = [(title, [g for g in names if g in groups]) for title, names in layers]
    placed = [(title, names) for title, names in placed if names]
    named = {g for _, names in placed for g in names}
    rest = sorted(g for g in groups if g not in named)
    if rest:
        log.info("import graph: no layer names %s; drawn in a row of their own", ", ".join(rest))
        placed.append((UNLAYERED, rest))
    return Graph(groups, edges, placed)


def group_of_file(relative: Path) -> str:
    """The group of the package's file at ``relative`` (a path inside the package)."""
    path = relative.as_posix()
    matches = [prefix for prefix in SUBGROUPS if path.startswith(prefix)]
    if matches:
        return SUBGROUPS[max(matches, key=len)]
    if len(relative.parts) > 1:
        return relative.parts[0]
    return relative.stem  # a top-level module (``__init__`` is :data:`ROOT`)


def imports_of(tree: ast.Module, package: str):
    """(dotted module, kind) for each import of the package's own modules in ``tree``."""

    def visit(node: ast.AST, kind: str):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                for statement in child.body:
                    yield from visit_one(statement, "typing")
                for statement in child.orelse:
                    yield from visit_one(statement, kind)
            else:
                yield from visit_one(child, kind)

    def visit_one(node: ast.AST, kind: str):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE:
                    yield alias.name, kind
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            if base.split(".")[0] == PACKAGE:
                for alias in node.names:
                    # `from package import module` imports the module; a name, the package
                    yield f"{base}.{alias.name}", kind
        inner = "function" if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) else kind
        if kind == "typing":
            inner = kind
        yield from visit(node, inner)

    yield from visit(tree, "module")


# --- the layout ------------------------------------------------------------------------

BOX_HEIGHT = 40
ROW_GAP = 58
MARGIN = 16
LABELS = 112  # the layer titles' column
FONT = 13  # the boxes' labels, monospace: a character is 0.6 em wide
GAPS = {(False, False): 18, (False, True): 9, (True, False): 9, (True, True): 5}
COLOURS = [  # one a layer, for its boxes and the arrows leaving them
    "#1f5fa8",
    "#2e7d32",
    "#6a3d9a",
    "#8c564b",
    "#00838f",
    "#37474f",
    "#b07d00",
    "#283593",
    "#8a8d1f",
    "#4e5d6c",
    "#795548",
]
UP = "#d62728"
#: An import made at a module's top, inside a function, or for type checkers only.
DASHES = {
    "module": "",
    "function": ' stroke-dasharray="5 3"',
    "typing": ' stroke-dasharray="1.5 2.5"',
}
UNLAYERED_COLOUR = "#777777"


@dataclass
class Node:
    key: str
    row: int
    width: float
    dummy: bool
    x: float = 0.0


@dataclass
class Chain:
    """An edge between rows, through one dummy node per row it crosses, top to bottom."""

    edge: Edge
    nodes: list[str]
    up: bool  # drawn from the bottom node to the top one


def box_width(group: Group) -> float:
    label = len(group.label) * FONT * 0.6
    note = len(module_count(group)) * 10.5 * 0.56
    return round(max(label, note, 5 * FONT * 0.6) + 20)


def module_count(group: Group) -> str:
    if not group.package:
        return ""
    count = len(group.modules)
    return f"{count} module" + ("s" if count != 1 else "")


def layout(graph: Graph):
    nodes: dict[str, Node] = {}
    rows: list[list[str]] = []
    for row, (_, names) in enumerate(graph.layers):
        rows.append(list(names))
        for name in names:
            nodes[name] = Node(name, row, box_width(graph.groups[name]), dummy=False)
    chains: list[Chain] = []
    sideways: list[Edge] = []
    for edge in graph.edges.values():
        top, bottom = edge.source, edge.target
        up = nodes[top].row > nodes[bottom].row
        if up:
            top, bottom = bottom, top
        if nodes[top].row == nodes[bottom].row:
            sideways.append(edge)
            continue
        chain = [top]
        for row in range(nodes[top].row + 1, nodes[bottom].row):
            key = f"{edge.source}>{edge.target}@{row}"
            nodes[key] = Node(key, row, 0, dummy=True)
            rows[row].append(key)
            chain.append(key)
        chain.append(bottom)
        chains.append(Chain(edge, chain, up))
    above: dict[str, list[str]] = {key: [] for key in nodes}
    below: dict[str, list[str]] = {key: [] for key in nodes}
    for chain in chains:
        for upper, lower in pairwise(chain.nodes):
            below[upper].append(lower)
            above[lower].append(upper)
    rows = order(rows, above, below)
    place(rows, nodes, above, below)
    return nodes, rows, chains, sideways


def crossings(rows: list[list[str]], below: dict[str, list[str]]) -> int:
    total = 0
    for upper, lower in pairwise(rows):
        position = {key: i for i, key in enumerate(lower)}
        pairs = sorted((i, position[b]) for i, a in enumerate(upper) for b in below[a])
        seen: list[int] = []
        for _, b in pairs:
            total += len(seen) - bisect_right(seen, b)
            insort(seen, b)
    return total


def order(rows, above, below) -> list[list[str]]:
    """Rows ordered to cross few edges: barycentre sweeps, keeping the best seen."""
    best, fewest = [list(row) for row in rows], crossings(rows, below)
    for sweep in range(24):
        downward = sweep % 2 == 0
        sequence = range(1, len(rows)) if downward else range(len(rows) - 2, -1, -1)
        for r in sequence:
            neighbours = above if downward else below
            position = {key: i for i, key in enumerate(rows[r - 1 if downward else r + 1])}
            weight = {}
            for i, key in enumerate(rows[r]):
                linked = [position[n] for n in neighbours[key]]
                weight[key] = sum(linked) / len(linked) if linked else i
            rows[r] = sorted(rows[r], key=weight.__getitem__)
        count = crossings(rows, below)
        if count < fewest:
            best, fewest = [list(row) for row in rows], count
    return best


def place(rows, nodes, above, below) -> None:
    """x of every node: near its neighbours, in its row's order, never overlapping."""

    def gap(a: Node, b: Node) -> float:
        return (a.width + b.width) / 2 + GAPS[(a.dummy, b.dummy)]

    for row in rows:
        x = 0.0
        for i, key in enumerate(row):
            if i:
                x += gap(nodes[row[i - 1]], nodes[key])
            nodes[key].x = x
        for key in row:
            nodes[key].x -= x / 2
    for sweep in range(40):
        sequence = rows if sweep % 2 == 0 else rows[::-1]
        for row in sequence:
            wanted = []
            for key in row:
                linked = [
                    (n, 4.0 if nodes[n].dummy and nodes[key].dummy else 1.0)
                    for n in above[key] + below[key]
                ]
                if linked:
                    total = sum(w for _, w in linked)
                    wanted.append(sum(nodes[n].x * w for n, w in linked) / total)
                else:
                    wanted.append(nodes[key].x)
            separations = [gap(nodes[a], nodes[b]) for a, b in pairwise(row)]
            for key, x in zip(row, isotonic(wanted, separations), strict=True):
                nodes[key].x = x
    left = min(node.x - node.width / 2 for node in nodes.values())
    for node in nodes.values():
        node.x += MARGIN + LABELS - left


def isotonic(wanted: list[float], separations: list[float]) -> list[float]:
    """The x nearest ``wanted`` (least squares) with x[i+1] - x[i] >= separations[i]."""
    offsets = [0.0]
    for separation in separations:
        offsets.append(offsets[-1] + separation)
    blocks: list[list[float]] = []  # [mean, count]
    for want, offset in zip(wanted, offsets, strict=True):
        blocks.append([want - offset, 1])
        while len(blocks) > 1 and blocks[-2][0] > blocks[-1][0]:
            mean, count = blocks.pop()
            blocks[-1] = [
                (blocks[-1][0] * blocks[-1][1] + mean * count) / (blocks[-1][1] + count),
                blocks[-1][1] + count,
            ]
    shifted = [mean for mean, count in blocks for _ in range(int(count))]
    return [y + offset for y, offset in zip(shifted, offsets, strict=True)]


# --- the picture -----------------------------------------------------------------------


def draw(graph: Graph) -> str:
    nodes, rows, chains, sideways = layout(graph)

    def top(row: int) -> float:
        return MARGIN + row * (BOX_HEIGHT + ROW_GAP)

    width = max(node.x + node.width / 2 for node in nodes.values()) + MARGIN
    height = top(len(rows)) - ROW_GAP + 12 + 56
    colour = {}
    for i, (title, names) in enumerate(graph.layers):
        for name in names:
            colour[name] = UNLAYERED_COLOUR if title == UNLAYERED else COLOURS[i % len(COLOURS)]

    # the ports: where each chain leaves or enters a box, spread along its edge
    ports: dict[tuple[int, str], float] = {}
    ends: dict[tuple[str, str], list[tuple[float, int, str]]] = {}
    for index, chain in enumerate(chains):
        first, second = chain.nodes[0], chain.nodes[1]
        last, before = chain.nodes[-1], chain.nodes[-2]
        ends.setdefault((first, "bottom"), []).append((nodes[second].x, index, "start"))
        ends.setdefault((last, "top"), []).append((nodes[before].x, index, "end"))
    for (key, _), attached in ends.items():
        node = nodes[key]
        attached.sort()
        for i, (_, index, end) in enumerate(attached):
            share = (i + 0.5) / len(attached)
            ports[(index, end)] = node.x - 0.42 * node.width + 0.84 * node.width * share

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
        f'viewBox="0 0 {width:.0f} {height:.0f}" font-family="sans-serif">',
        "<title>cmarl-cd: the import graph of its modules, grouped by top-level module or "
        "subpackage, in layers</title>",
        "<defs>",
    ]
    for name in sorted(set(colour.values()) | {UP}):
        out.append(
            f'<marker id="head{name[1:]}" viewBox="0 0 10 10" refX="9" refY="5" '
            f'markerUnits="userSpaceOnUse" markerWidth="9" markerHeight="9" orient="auto">'
            f'<path d="M0,0 L10,5 L0,10 z" fill="{name}"/></marker>'
        )
    out.append("</defs>")
    out.append(f'<rect width="{width:.0f}" height="{height:.0f}" fill="#ffffff"/>')
    for row, (title, _) in enumerate(graph.layers):
        y = top(row)
        if row % 2 == 0:
            out.append(
                f'<rect x="0" y="{y - 10:.0f}" width="{width:.0f}" height="{BOX_HEIGHT + 20}" '
                'fill="#f3f5f8"/>'
            )
        out.append(
            f'<text x="{MARGIN}" y="{y + BOX_HEIGHT / 2 + 4:.0f}" font-size="12" '
            f'font-style="italic" fill="#555">{html.escape(title)}</text>'
        )

    def path(points: list[tuple[float, float]]) -> str:
        d = [f"M{points[0][0]:.1f},{points[0][1]:.1f}"]
        for (x1, y1), (x2, y2) in pairwise(points):
            if x1 == x2:  # through a row, between its boxes
                d.append(f"L{x2:.1f},{y2:.1f}")
            else:
                middle = (y1 + y2) / 2
                d.append(f"C{x1:.1f},{middle:.1f} {x2:.1f},{middle:.1f} {x2:.1f},{y2:.1f}")
        return " ".join(d)

    def edge_title(edge: Edge) -> str:
        lines = [f"{graph.groups[edge.source].label} imports {graph.groups[edge.target].label}:"]
        lines += [
            f"{a} → {b}" + ("" if kind == "module" else f" ({kind})")
            for a, b, kind in sorted(set(edge.imports))
        ]
        return html.escape("\n".join(lines))

    def stroke(edge: Edge) -> str:
        up = graph.points_up(edge)
        paint = UP if up else colour[edge.source]
        dash = DASHES[edge.kind]
        return (
            f'fill="none" stroke="{paint}" stroke-width="{2.4 if up else 1.2}" '
            f'stroke-opacity="{1 if up else 0.75}"{dash} marker-end="url(#head{paint[1:]})"'
        )

    drawn: list[tuple[bool, str]] = []
    for index, chain in enumerate(chains):
        first, last = nodes[chain.nodes[0]], nodes[chain.nodes[-1]]
        points = [(ports[(index, "start")], top(first.row) + BOX_HEIGHT)]
        for key in chain.nodes[1:-1]:
            node = nodes[key]
            points += [(node.x, top(node.row) - 10), (node.x, top(node.row) + BOX_HEIGHT + 10)]
        points.append((ports[(index, "end")], top(last.row)))
        if chain.up:
            points.reverse()
        drawn.append(
            (
                graph.points_up(chain.edge),
                f'<path d="{path(points)}" {stroke(chain.edge)}><title>{edge_title(chain.edge)}'
                "</title></path>",
            )
        )
    for edge in sideways:
        source, target = nodes[edge.source], nodes[edge.target]
        y = top(source.row)
        rightward = target.x > source.x
        sign = 1 if rightward else -1
        x1 = source.x + sign * source.width / 2
        x2 = target.x - sign * target.width / 2
        if rightward:  # under the row
            y1, bend = y + BOX_HEIGHT - 8, y + BOX_HEIGHT + 30
        else:  # over the row
            y1, bend = y + 8, y - 30
        d = (
            f"M{x1:.1f},{y1:.1f} C{x1 + sign * 24:.1f},{bend:.1f} "
            f"{x2 - sign * 24:.1f},{bend:.1f} {x2:.1f},{y1:.1f}"
        )
        drawn.append(
            (
                graph.points_up(edge),
                f'<path d="{d}" {stroke(edge)}><title>{edge_title(edge)}</title></path>',
            )
        )
    out += [svg for up, svg in drawn if not up]

    for name, group in graph.groups.items():
        node = nodes[name]
        y = top(node.row)
        left = node.x - node.width / 2
        paint = colour[name]
        modules = "\n".join(sorted(group.modules))
        out.append(f"<g><title>{html.escape(group.label)}\n{html.escape(modules)}</title>")
        out.append(
            f'<rect x="{left:.1f}" y="{y:.1f}" width="{node.width:.0f}" height="{BOX_HEIGHT}" '
            f'rx="5" fill="#ffffff" stroke="{paint}" stroke-width="{2 if group.package else 1.2}"/>'
        )
        note = module_count(group)
        label_y = y + BOX_HEIGHT / 2 + (0 if note else 4.5)
        out.append(
            f'<text x="{node.x:.1f}" y="{label_y:.1f}" font-family="monospace" '
            f'font-size="{FONT}" text-anchor="middle" fill="#111">{html.escape(group.label)}</text>'
        )
        if note:
            out.append(
                f'<text x="{node.x:.1f}" y="{y + BOX_HEIGHT / 2 + 14:.1f}" font-size="10.5" '
                f'text-anchor="middle" fill="#666">{note}</text>'
            )
        out.append("</g>")
    out += [svg for up, svg in drawn if up]

    # the legend
    y = height - 30
    x = MARGIN
    sample = colour[graph.layers[0][1][0]]
    items = [
        (sample, "", "imports (coloured by the importing layer)"),
        (sample, ' stroke-dasharray="5 3"', "imported only inside functions"),
        (UP, "", "points up the layers"),
    ]
    for paint, dash, text in items:
        out.append(
            f'<path d="M{x},{y} L{x + 34},{y}" stroke="{paint}" stroke-width="2"{dash} '
            f'marker-end="url(#head{paint[1:]})"/>'
        )
        out.append(f'<text x="{x + 42}" y="{y + 4}" font-size="12" fill="#333">{text}</text>')
        x += 42 + len(text) * 6.4 + 28
    out.append(
        f'<text x="{MARGIN}" y="{y + 22}" font-size="11" fill="#777">Drawn from the imports in '
        f"src/{PACKAGE} when the documentation is built; a box is a top-level module or a "
        "subpackage (/). Opened on its own, each box and arrow names its modules and imports."
        "</text>"
    )
    out.append("</svg>")
    return "\n".join(out) + "\n"


def notes(graph: Graph) -> str:
    """The Markdown under the picture: how to read it, and every import that points up."""
    up = [edge for edge in graph.edges.values() if graph.points_up(edge)]
    text = [
        f"[![The import graph of the package's modules, in layers]({IMAGE})]({IMAGE})",
        "",
        f"Drawn from the code when the site is built (`docs/hooks/{Path(__file__).name}`): "
        f"one box per top-level module or subpackage of `{PACKAGE}`, in the layers the hook "
        "lists, top to bottom; an arrow from a box to each box it imports, dashed when the "
        "import is inside a function (made when needed).",
    ]
    if not up:
        text += ["", "No import points up the layers."]
        return "\n".join(text) + "\n"
    text += ["", "Imports that point up the layers (red):", ""]
    for edge in sorted(up, key=lambda e: (e.source, e.target)):
        files = sorted({(a, b) for a, b, _ in edge.imports})
        shown = "; ".join(f"`{a}` imports `{b}`" for a, b in files)
        source, target = graph.groups[edge.source].label, graph.groups[edge.target].label
        text.append(f"- `{source}` → `{target}`: {shown}")
    return "\n".join(text) + "\n"


# --- the hook --------------------------------------------------------------------------

_graph: Graph | None = None


def on_files(files, config):
    from mkdocs.structure.files import File

    global _graph
    _graph = build_graph(Path(config["config_file_path"]).parent / SOURCE)
    files.append(File.generated(config, IMAGE, content=draw(_graph)))
    return files


def on_page_markdown(markdown, page, config, files):
    if page.file.src_uri != PAGE:
        return markdown
    if MARKER not in markdown or _graph is None:
        log.warning("import graph: %s has no %s to put the diagram in", PAGE, MARKER)
        return markdown
    return markdown.replace(MARKER, notes(_graph))


if __name__ == "__main__":
    root = Path(__file__).resolve().parents[2]
    sys.stdout.write(draw(build_graph(root / SOURCE)))
