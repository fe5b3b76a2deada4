"""The field study's tables and curves (benchmarks/field_study.sh), from its store.

Reads what ``cmarl-cd report --store STORE --format json`` gives (the study's numbers are
exactly the report's) and prints, per figure of the field (the maximum return and the
average return over the curve, each with its 95 % interval over the seeds, EPyMARL's
figures), one Markdown table with the tasks as rows and the learners as columns, the best
of each row in bold, the random policy's mean return as the floor, a cell of fewer seeds
than the protocol's marked with how many it holds; then which tasks and learners the
store does not hold yet, or not all of their seeds. ``--figure`` draws every task's mean curves, one
panel a task; ``--page`` writes the tables and the list into the documentation page's
marked blocks (``<!-- study-max -->`` ... ``<!-- /study-max -->``, ``study-average``,
``study-missing``).

    python benchmarks/field_study_tables.py --store results/field/study/store.sqlite \
        --figure docs/field-study.png --page docs/field.md
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

#: The study's tasks, in its order (benchmarks/field_study.sh).
TASKS = (
    "foraging:8x8-2p-2f-coop",
    "foraging:2s-8x8-2p-2f-coop",
    "foraging:10x10-3p-3f",
    "foraging:2s-10x10-3p-3f",
    "foraging:15x15-3p-5f",
    "foraging:15x15-4p-3f",
    "foraging:15x15-4p-5f",
    "simple_spread",
)
#: How the store names a task given by its short name (simple_spread's defaults spelled
#: out).
STORED = {"simple_spread": "simple_spread:N=3,local_ratio=0.5,max_cycles=25"}
#: The setting that tells the study's design of deep CMARL-CD where states do not recur
#: (field_study.sh's ``shares`` part, the shares with standardised rewards) from the
#: design it replaced (``shares-cold``, whose runs stay in the store, in no column): as
#: its label in the store writes it, and as its stored settings do.
DESIGN_LABEL = "standardise_rewards=True"
DESIGN_CONFIG = '"standardise_rewards":true'
#: The study's learners: the column's name, how its label in the store begins and what
#: else it must hold.
LEARNERS = (
    ("IQL", "Deep IQL (EPyMARL", ""),
    ("hysteretic DQN", "Hysteretic DQN (EPyMARL", ""),
    ("VDN", "VDN (EPyMARL", ""),
    ("QMIX", "QMIX (EPyMARL", ""),
    ("deep CMARL-CD", "Deep CMARL-CD (gamma=0.99)", ""),
    ("deep CMARL-CD (shares)", "Deep CMARL-CD (critic_bootstrap='greedy'", DESIGN_LABEL),
)
RANDOM = "random policy"
#: The study's seeds a task and learner (benchmarks/field_protocol.sh, full protocol).
SEEDS = 5
#: The two figures of a curve (field_metrics): the best point, the mean of every point.
FIGURES = (("max_return", "maximum return"), ("average_return", "average return"))


def column(label: str) -> str | None:
    """The study's column of a learner's label in the store (None: not the study's)."""
    found = (name for name, start, held in LEARNERS if label.startswith(start) and held in label)
    return next(found, None)


def study(report: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per task of the study: its learners' field figures by column, the random floor,
    and the mean curves ``{column: [(step, mean return), ...]}``."""
    tasks: dict[str, dict[str, Any]] = {}
    short = {STORED.get(task, task): task for task in TASKS}
    for doc in report.get("train", []):
        if doc["game"] not in short:
            continue
        task = tasks.setdefault(
            short[doc["game"]], {"field": {}, "floor": None, "curves": {}, "seeds": {}}
        )
        for row in doc["rows"]:
            if row["algorithm"] == "random":
                task["floor"] = row["mean_return"]
        for label, figures in doc["field"].items():
            if (name := column(label)) is not None:
                task["field"][name] = figures
        for label, runs in doc["curves"].items():
            name = RANDOM if label == RANDOM else column(label)
            if name is not None and name != RANDOM:
                task["seeds"][name] = len(runs)
            if name is not None and runs:
                points = zip(*runs, strict=True)
                task["curves"][name] = [(p[0][0], sum(x[1] for x in p) / len(p)) for p in points]
    return tasks


def partial(seeds: int | None, expected: int) -> str:
    """`` (n of N seeds)`` where a learner holds fewer seeds than the protocol's, else
    nothing (nor where the report shows no curves to count)."""
    return "" if seeds is None or seeds >= expected else f" ({seeds} of {expected} seeds)"


def cell(
    figures: dict[str, Any], key: str, best: bool, seeds: int | None = None,
    expected: int = SEEDS,
) -> str:  # fmt: skip
    value = f"{figures[key]:.3f}"
    low, high = figures.get(f"{key}_low"), figures.get(f"{key}_high")
    interval = "" if low is None or math.isnan(low) else f" [{low:.3f}, {high:.3f}]"
    return (f"**{value}**" if best else value) + interval + partial(seeds, expected)


def table(tasks: dict[str, dict[str, Any]], key: str, expected: int = SEEDS) -> list[str]:
    """One Markdown table of ``key`` (a field figure): tasks as rows, learners as
    columns, the best of each row in bold (every learner at the row's best: ties), a
    cell of fewer than ``expected`` seeds marked with how many it holds."""
    names = [name for name, *_ in LEARNERS]
    lines = [
        "| task | " + " | ".join(names) + " | random |",
        "|---|" + "---|" * (len(names) + 1),
    ]
    for game in TASKS:
        if game not in tasks:
            continue
        found, seeds = tasks[game]["field"], tasks[game].get("seeds", {})
        top = max((found[n][key] for n in names if n in found), default=None)
        cells = [
            cell(found[n], key, found[n][key] == top, seeds.get(n), expected) if n in found else "–"
            for n in names
        ]
        floor = tasks[game]["floor"]
        cells.append("–" if floor is None else f"{floor:.3f}")
        lines.append(f"| {game.removeprefix('foraging:')} | " + " | ".join(cells) + " |")
    return lines


def missing(tasks: dict[str, dict[str, Any]], expected: int = SEEDS) -> list[str]:
    """``task: learner, ...`` for every pair the store does not hold yet, and
    ``learner (n of N seeds)`` for one that holds fewer than ``expected`` seeds."""
    lines = []
    for game in TASKS:
        held = tasks.get(game, {}).get("field", {})
        seeds = tasks.get(game, {}).get("seeds", {})
        absent = []
        for name, *_ in LEARNERS:
            mark = partial(seeds.get(name), expected) if name in held else ""
            if name not in held or mark:
                absent.append(name + mark)
        if absent:
            lines.append(f"{game}: " + ", ".join(absent))
    return lines


def fill(page: str, block: str, lines: list[str]) -> str:
    """``page`` with the text between ``<!-- block -->`` and ``<!-- /block -->``
    replaced by ``lines``."""
    start, end = f"<!-- {block} -->", f"<!-- /{block} -->"
    if start not in page or end not in page:
        raise ValueError(f"the page has no block {start} ... {end}")
    head, rest = page.split(start, 1)
    _, tail = rest.split(end, 1)
    return head + start + "\n" + "\n".join(lines) + ("\n" if lines else "") + end + tail


#: The store's name of each learner of the study (deep CMARL-CD's two by their design).
ALGORITHMS = {"deep-iql": "IQL", "hysteretic-dqn": "hysteretic DQN", "vdn": "VDN", "qmix": "QMIX"}


def hours(store: Path) -> dict[str, dict[str, float]]:
    """Per task and learner of the study, the hours its runs took (the store's wall
    seconds of each run: a seed's share of its stacked batch)."""
    import sqlite3

    spent: dict[str, dict[str, float]] = {}
    with contextlib.closing(sqlite3.connect(f"file:{store}?mode=ro", uri=True)) as db:
        rows = db.execute("SELECT experiment, algorithm, config, wall_seconds FROM runs")
        for experiment, algorithm, config, seconds in rows:
            game = json.loads(config).get("game", {})
            task = f"{experiment}:{game.get('task')}" if isinstance(game, dict) else None
            task = "simple_spread" if task == STORED["simple_spread"] else task
            if algorithm == "deep-cmarl-cd":
                settings = config.replace(" ", "")
                if '"critic_form":"degrees"' not in settings:
                    name = "deep CMARL-CD"
                elif DESIGN_CONFIG in settings:
                    name = "deep CMARL-CD (shares)"
                else:  # the design the study's replaced
                    name = None
            else:
                name = ALGORITHMS.get(algorithm)
            if task in TASKS and name is not None:
                row = spent.setdefault(task, {})
                row[name] = row.get(name, 0.0) + seconds / 3600
    return spent


def time_table(spent: dict[str, dict[str, float]]) -> list[str]:
    """Hours per task (rows) and learner (columns), with each row's and column's sum."""
    names = [name for name, *_ in LEARNERS]
    lines = ["| task | " + " | ".join(names) + " | all |", "|---|" + "---|" * (len(names) + 1)]
    for game in TASKS:
        if game in spent:
            row = spent[game]
            cells = [f"{row[n]:.2f}" if n in row else "–" for n in names]
            total = sum(row.values())
            lines.append(
                f"| {game.removeprefix('foraging:')} | " + " | ".join(cells) + f" | {total:.2f} |"
            )
    sums = [sum(spent[g].get(n, 0.0) for g in spent) for n in names]
    lines.append("| all | " + " | ".join(f"{h:.2f}" for h in sums) + f" | {sum(sums):.2f} |")
    return lines


def draw(tasks: dict[str, dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    games = [g for g in TASKS if g in tasks]
    cols = min(4, len(games))
    rows = math.ceil(len(games) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3 * rows), squeeze=False)
    for ax, game in zip(axes.flat, games, strict=False):
        for name, curve in tasks[game]["curves"].items():
            steps, returns = zip(*curve, strict=True)
            style = {"color": "grey", "linestyle": ":"} if name == RANDOM else {}
            ax.plot([s / 1e6 for s in steps], returns, label=name, **style)
        ax.set_title(game.removeprefix("foraging:"), fontsize=10)
        ax.set_xlabel("environment steps (millions)")
        ax.set_ylabel("greedy return")
    for ax in list(axes.flat)[len(games) :]:
        ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def read(store: Path) -> dict[str, Any]:
    """``cmarl-cd report --store STORE --format json``, read; ValueError with the report's
    last line of error where it fails."""
    done = subprocess.run(
        [sys.executable, "-m", "cmarlcd", "report", "--store", str(store), "--format", "json"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines()
        raise ValueError(lines[-1] if lines else f"error: cmarl-cd report failed on {store}")
    return json.loads(done.stdout)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--store", type=Path, help="the study's store (runs cmarl-cd report)")
    p.add_argument("--report", type=Path, help="or a report already written (JSON)")
    p.add_argument("--figure", type=Path, help="draw the curves into this PNG")
    p.add_argument("--page", type=Path, help="write the tables into this page's blocks")
    p.add_argument("--seeds", type=int, default=SEEDS,
                   help=f"the protocol's seeds; fewer are marked (default {SEEDS})")  # fmt: skip
    args = p.parse_args(argv)
    if args.seeds < 1:
        print(f"error: --seeds must be >= 1 (got {args.seeds})", file=sys.stderr)
        return 2
    if (args.store is None) == (args.report is None):
        print("error: give one of --store and --report", file=sys.stderr)
        return 2
    source = args.store if args.store is not None else args.report
    for path in (source, args.page):
        if path is not None and not path.is_file():
            print(f"error: no such file: {path}", file=sys.stderr)
            return 2
    if args.store is not None:
        try:
            report = read(args.store)
        except ValueError as error:
            print(error, file=sys.stderr)
            return 2
    else:
        try:
            report = json.loads(args.report.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError):
            print(f"error: {args.report} is not a report (cmarl-cd report --format json)",
                  file=sys.stderr)  # fmt: skip
            return 2
    tasks = study(report)
    for key, title in FIGURES:
        print(f"\n{title} (95 % interval over the seeds; bold: the row's best)\n")
        print("\n".join(table(tasks, key, args.seeds)))
    spent = hours(args.store) if args.store is not None else None
    if spent is not None:
        print("\nhours of one core (the runs' wall seconds)\n")
        print("\n".join(time_table(spent)))
    absent = missing(tasks, args.seeds)
    print("\nnot in the store yet:" if absent else "\nevery task and learner is in the store")
    print("\n".join(absent))
    if args.figure is not None:
        draw(tasks, args.figure)
        print(f"figure: {args.figure}")
    if args.page is not None:
        page = args.page.read_text()
        try:
            for key, _ in FIGURES:
                page = fill(page, "study-" + key.split("_")[0], table(tasks, key, args.seeds))
            page = fill(page, "study-missing", [f"- {line}" for line in absent] or ["none"])
            if spent is not None:
                page = fill(page, "study-hours", time_table(spent))
        except ValueError as error:
            print(f"error: {args.page}: {error}", file=sys.stderr)
            return 2
        args.page.write_text(page)
        print(f"page: {args.page}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
