"""Every ``cmarl-cd ...`` line of the README and the docs parses with the CLI's own click
command, nothing run (issue 30): the documentation cannot drift from the code.

Lines come from fenced code blocks (continued by a trailing backslash, split at ``&&``, ``;``
and ``|``, ``#`` comments dropped) and inline code spans. A concrete line is parsed as click
parses it; a synopsis (``[--rounds 10]``, ``--case 1|2``, ``N``, ``<path>``, ``…``) has its
option names checked instead, each option that takes a value showing one, a flag none.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
import typer
import typer.main

from cmarlcd.cli import app

try:  # typer 0.2x carries its own copy of click
    from typer._click.core import Command, Context
    from typer._click.exceptions import UsageError
except ImportError:  # pragma: no cover  (an older typer: click itself)
    from click import Command, Context, UsageError

ROOT = Path(__file__).resolve().parents[1]
DOCS = (ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")))
CLI = typer.main.get_command(app)
#: The context every command is parsed under (it carries the app's ``-h``/``--help``).
PARENT = Context(CLI, info_name="cmarl-cd", **CLI.context_settings)

FENCE = re.compile(r"^\s*(```|~~~)")
#: An inline code span, on one line or across the lines of one paragraph.
SPAN = re.compile(r"(?<!`)(`+)((?:(?!\n\s*\n)[^`])+)\1(?!`)")
#: A span that is a command of this CLI (not ``cmarl-cd-x``, not the learner ``cmarl-cd``).
INLINE_COMMAND = re.compile(r"^(\$\s+)?cmarl-cd\s+\S")
OPERATORS = {"&&", "||", "|", ";", "&"}
#: Values that stand for something: ``N``, ``PATH``, ``MODULE:FACTORY``, ``<file>``, ``…``.
PLACEHOLDER = re.compile(r"[A-Z][A-Z0-9_]*(:[A-Z][A-Z0-9_]*)?|.*(…|\.\.\.|<.+>|[][|]).*")

Found = dict[tuple[str, int], list[tuple[str, ...]]]


def commands_in(text: str, inline: bool) -> list[tuple[str, ...]]:
    """The arguments after ``cmarl-cd`` of each command in a shell line (in an inline
    span ``|`` separates alternatives and ``#`` is text, not a pipe or a comment)."""
    lexer = shlex.shlex(text, posix=True, punctuation_chars="&;" if inline else "&;|")
    lexer.whitespace_split = True
    lexer.commenters = "" if inline else "#"
    segments: list[list[str]] = [[]]
    for token in lexer:
        if token in OPERATORS:
            segments.append([])
        else:
            segments[-1].append(token)
    segments = [s[1:] if s[:1] == ["$"] else s for s in segments]
    return [tuple(s[1:]) for s in segments if s[:1] == ["cmarl-cd"]]


def collect(name: str, markdown: str, found: Found) -> None:
    """Add every command line of the Markdown text of file ``name`` to ``found``."""
    lines = markdown.splitlines()
    prose, fenced, start, pending = list(lines), False, 0, ""
    for number, line in enumerate(lines, 1):
        if FENCE.match(line) or fenced:
            prose[number - 1] = ""
        if FENCE.match(line):
            fenced, pending = not fenced, ""
            continue
        if not fenced:
            continue
        start = start if pending else number
        pending += line
        if pending.endswith("\\"):
            pending = pending[:-1] + " "
            continue
        if re.search(r"(^|[\s;&|])cmarl-cd(\s|$)", pending) and (
            commands := commands_in(pending, inline=False)
        ):
            found.setdefault((name, start), []).extend(commands)
        pending = ""
    text = "\n".join(prose)
    for match in SPAN.finditer(text):
        body = " ".join(match.group(2).split())
        if INLINE_COMMAND.match(body):
            number = text.count("\n", 0, match.start()) + 1
            if commands := commands_in(body, inline=True):
                found.setdefault((name, number), []).extend(commands)


def synopsis_problem(command: Command, args: tuple[str, ...]) -> str | None:
    """Why a synopsis does not fit ``command``: an option it lacks, a value missing after
    an option that takes one, or a value after a flag; None if it fits."""
    context = PARENT if command is CLI else Context(command, parent=PARENT)
    params = {o: p for p in command.get_params(context) for o in p.opts + p.secondary_opts}
    words = [a.strip("[]") for a in args]
    for index, word in enumerate(words):
        if not word.startswith("-"):
            continue
        names = word.split("=")[0].split("/")  # --a/--b: a flag pair
        if unknown := [name for name in names if name not in params]:
            return f"no such option: {unknown[0]}"
        param = params[names[0]]
        flag = getattr(param, "is_flag", False) or getattr(param, "count", False)
        following = words[index + 1] if index + 1 < len(words) else None
        gives_value = "=" in word or (
            not args[index].endswith("]") and following is not None and following[:1] != "-"
        )
        if flag and gives_value:
            return f"{word} is a flag and takes no value"
        if not flag and not gives_value:
            return f"{word} needs a value"
    return None


def problem(args: tuple[str, ...]) -> str | None:
    """Why ``cmarl-cd *args`` does not parse, or None; nothing is run."""
    root = next((i for i, arg in enumerate(args) if not arg.startswith("-")), len(args))
    name, rest = (args[root], args[root + 1 :]) if root < len(args) else (None, ())
    if name == "COMMAND":  # a placeholder for each command
        problems = (synopsis_problem(c, rest) for c in CLI.commands.values())
        return next((f"COMMAND: {p}" for p in problems if p), None)
    command = CLI.commands.get(name) if name else None
    if name and command is None:
        return f"no such command: {name!r}"
    if command is not None and not rest and not root:
        return None  # prose naming a command (`cmarl-cd train`), not a line to run
    if any(PLACEHOLDER.fullmatch(a) for a in args):
        return synopsis_problem(CLI, args[:root]) or (
            synopsis_problem(command, rest) if command else None
        )
    try:
        if root:
            CLI.make_context("cmarl-cd", [*args[:root], *([name] if name else [])])
        if command is not None:
            command.make_context(name, list(rest), parent=PARENT)
    except typer.Exit:  # --help or --version: parsed, then stopped
        return None
    except UsageError as err:
        return err.format_message()
    return None


FOUND: Found = {}  # every documented command line, keyed by (file, line)
for _path in DOCS:
    collect(_path.relative_to(ROOT).as_posix(), _path.read_text(encoding="utf-8"), FOUND)


@pytest.mark.parametrize(("where", "commands"), FOUND.items(), ids=[f"{f}:{n}" for f, n in FOUND])
def test_documented_command_parses(where: tuple[str, int], commands: list[tuple[str, ...]]) -> None:
    """Each documented command line on this line of this file is one the CLI accepts."""
    failures = [
        f"{where[0]}:{where[1]}: `cmarl-cd {' '.join(args)}`: {why}"
        for args in commands
        if (why := problem(args)) is not None
    ]
    assert not failures, "\n".join(failures)


def test_collector_finds_the_documented_commands() -> None:
    """The collector itself can fail: it finds lines in each main page, and enough."""
    files = {file for file, _ in FOUND}
    assert {"README.md", "docs/cli.md", "docs/getting-started.md"} <= files
    assert sum(map(len, FOUND.values())) >= 60  # 77 when this test was written


SAMPLE = """Prose: `cmarl-cd` the learner, `results/cmarl-cd.sqlite`, cmarl-cd dsn, and
`cmarl-cd tournament --rounds 6
--seed-batch 3` across lines; `cmarl-cd --version`, `cmarl-cd COMMAND -h`.

```bash
pip install -e . && cmarl-cd reproduce --preset quick   # cmarl-cd dsn
cmarl-cd dsn --runs 2 \\
    --set "SETTINGS" | tee out.txt; cmarl-cd-other dsn
$ cmarl-cd theory --agents 7
```

```python
configs["cmarl-cd"]; x = "cmarl-cd dsn"
```
"""


def test_collector_reads_spans_fences_and_continuations() -> None:
    """Spans across lines, chains, continued lines, prompts; not prose, code, comments."""
    found: Found = {}
    collect("x.md", SAMPLE, found)
    assert found == {
        ("x.md", 2): [("tournament", "--rounds", "6", "--seed-batch", "3")],
        ("x.md", 3): [("--version",), ("COMMAND", "-h")],
        ("x.md", 6): [("reproduce", "--preset", "quick")],
        ("x.md", 7): [("dsn", "--runs", "2", "--set", "SETTINGS")],
        ("x.md", 9): [("theory", "--agents", "7")],
    }


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("cmarl-cd dsn --runs 3 --no-such-option 1", "--no-such-option"),
        ("cmarl-cd dsn [--runs N] [--no-such-option …]", "--no-such-option"),
        ("cmarl-cd scaling [--progress/--no-such-option]", "--no-such-option"),
        ("cmarl-cd COMMAND --no-such-option", "--no-such-option"),
        ("cmarl-cd --no-such-option dsn", "--no-such-option"),
        ("cmarl-cd no-such-command --runs 3", "no-such-command"),
        ("cmarl-cd no-such-command [--runs N]", "no-such-command"),
        ("cmarl-cd dsn --runs many", "'--runs'"),
        ("cmarl-cd evaluate --episodes 3", "'--policy'"),
        ("cmarl-cd dsn [--runs] [--json]", "--runs needs a value"),
        ("cmarl-cd dsn [--json N]", "--json is a flag"),
        ("cmarl-cd dsn --runs 3 --no-progress", None),
        ("cmarl-cd scaling [--progress/--no-progress] [--runs N]", None),
        ("cmarl-cd --version", None),
        ("cmarl-cd COMMAND --help", None),
    ],
)
def test_checker(line: str, expected: str | None) -> None:
    """A made-up wrong line fails, naming what is wrong; a right one passes."""
    (args,) = commands_in(line, inline=True)
    why = problem(args)
    assert why is None if expected is None else why is not None and expected in why


def test_ci_runs_the_readme_s_set_up_and_test_command_verbatim() -> None:
    """The README promises one command that installs and passes the tests, the one CI
    runs: a line of ``.ci/run`` is that command, character for character."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    commands = [line for line in readme if "pip install" in line and "pytest" in line]
    assert len(commands) == 1, commands
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert commands[0] in ci
