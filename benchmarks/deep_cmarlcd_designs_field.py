"""Deep CMARL-CD's designs at the field study's protocol, beside the study's VDN and
shares columns: one Markdown table per figure (maximum and average return, 95 % interval
over the seeds), the study's tasks as rows.

Each design's runs are a store of their own, made with the study's command for one
learner (``cmarl-cd field --tasks ... --learners deep-cmarl-cd --steps 2.05M --seeds 5
--eval-interval 50k --eval-episodes 100 --inputs own-observations --set
deep-cmarl-cd.design=NAME,deep-cmarl-cd.gamma=0.99 --store STORE``); the study's store
gives the columns beside them. Reads each store through ``cmarl-cd report``, so the
numbers are the report's.

    python benchmarks/deep_cmarlcd_designs_field.py --study results/field/study/store.sqlite \
        --design shares-range=results/deep-cmarlcd-shares/range-field.sqlite
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from field_study_tables import FIGURES, RANDOM, STORED, TASKS, cell, read, study

#: The study's columns shown beside the designs.
BESIDE = ("VDN", "deep CMARL-CD (shares)")


def design_figures(store: Path, deep_cmarlcd: bool = True) -> dict[str, dict[str, Any]]:
    """Per task, the field figures of the one deep CMARL-CD setting a design's store
    holds (the first, where it holds more); with ``deep_cmarlcd`` false, of the one
    other learner a baseline's store holds (not the random policy)."""
    short = {STORED.get(task, task): task for task in TASKS}
    found: dict[str, dict[str, Any]] = {}
    for doc in read(store).get("train", []):
        if doc["game"] not in short:
            continue
        for label, figures in doc["field"].items():
            if label.startswith("Deep CMARL-CD") is deep_cmarlcd and label != RANDOM:
                found.setdefault(short[doc["game"]], figures)
    return found


def table(columns: dict[str, dict[str, dict[str, Any]]], key: str) -> list[str]:
    """Tasks as rows, ``columns`` (name: task: figures) as columns, each row's best in
    bold; a column with no figure on any task (a study's column not computed yet) is left
    out."""
    names = [name for name, tasks in columns.items() if tasks]
    lines = ["| task | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for task in TASKS:
        held = {n: columns[n][task] for n in names if task in columns[n]}
        if not held:
            continue
        top = max(f[key] for f in held.values())
        cells = [cell(held[n], key, held[n][key] == top) if n in held else "–" for n in names]
        lines.append(f"| {task.removeprefix('foraging:')} | " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", type=Path, required=True, help="the field study's store")
    parser.add_argument(
        "--design", action="append", default=[], metavar="NAME=STORE",
        help="a design's name and the store of its runs (repeat)",
    )  # fmt: skip
    parser.add_argument(
        "--baseline", action="append", default=[], metavar="NAME=STORE",
        help="a baseline's runs in a store of their own (e.g. VDN reading the time left; "
        "repeat), after the designs",
    )  # fmt: skip
    args = parser.parse_args(argv)
    given_columns = [("--design", g, True) for g in args.design]
    given_columns += [("--baseline", g, False) for g in args.baseline]
    designs = []
    for flag, given, deep in given_columns:
        name, _, store = given.partition("=")
        if not name or not store:
            print(f"error: {flag} takes NAME=STORE (got {given!r})", file=sys.stderr)
            return 2
        designs.append((name, store, deep))
    for path in [args.study, *(Path(store) for _, store, _ in designs)]:
        if not path.is_file():
            print(f"error: no store at {path}", file=sys.stderr)
            return 2
    try:
        tasks = study(read(args.study))
        columns = {
            n: {t: tasks[t]["field"][n] for t in tasks if n in tasks[t]["field"]} for n in BESIDE
        }
        for name, store, deep in designs:
            columns[name] = design_figures(Path(store), deep)
    except ValueError as error:
        print(error, file=sys.stderr)
        return 2
    for key, title in FIGURES:
        print(f"\n{title} (95 % interval over the seeds; bold: the row's best)\n")
        print("\n".join(table(columns, key)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
