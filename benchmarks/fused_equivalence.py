"""Study: are the fused step's runs equivalent to autograd's? Two one-sided tests per cell.

The fused gradient step (``step=fused``) changes float rounding, so its runs follow other
trajectories than autograd's; this study computes both with the same seeds into one
store (``cmarl-cd`` commands in subprocesses: resumable, an interrupted study goes on
where it stopped) and tests each cell for equivalence within margins declared here,
before any run (:data:`MARGINS`), by Schuirmann's TOST at α = 0.05
(:mod:`cmarlcd.experiments.equivalence`):

* ``dsn``: the VDN and QMIX rows of Tables 3-7: each run's success rate and mean steps at
  each learning budget L;
* ``tournament``: VDN and QMIX on the battlefield, each pairing's per-match win rate of
  its first learner (the share of the evaluation episodes it wins);
* ``head-to-head``: each of VDN and QMIX with the fused step against itself with
  autograd's, in the same matches (positions alternating by round): per match, the fused
  side's win rate minus the even split of the episodes not tied, ``(100 - ties) / 2``,
  which is zero in expectation when the two steps play alike; tested paired
  (:func:`cmarlcd.experiments.equivalence.paired_tost`) within the win rate's margin.
  Computed in this process (the command line plays a learner once per pairing).
* ``field``: deep CMARL-CD at a named design (``--design``, the shares' fused step by
  default: ``shares-range-shared``) on the field's tasks (``--tasks``), ``cmarl-cd
  field`` at the study's evaluation (every 50k steps unless told) for ``--steps``: each run's
  average return over its curve (the seeds' values the field's average return is the
  mean of) and its final return, within margins of the task family's returns
  (:data:`FIELD_MARGINS`).

Usage:
    python benchmarks/fused_equivalence.py dsn --runs 50 --episodes 100k
    python benchmarks/fused_equivalence.py dsn --algorithms deep-cmarl-cd --runs 50
    python benchmarks/fused_equivalence.py tournament --runs 50 --learn-episodes 20k
    python benchmarks/fused_equivalence.py head-to-head --runs 200 --learn-episodes 20k
    python benchmarks/fused_equivalence.py field --runs 30 --steps 500k \
        --tasks foraging:8x8-2p-2f-coop,simple_spread --design shares-range-shared
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

from cmarlcd.experiments.equivalence import ALPHA, paired_tost, tost

#: Margins declared before the runs: how far the fused runs' mean may lie from autograd's
#: and still count as the same result (the units the reports print: points of a rate,
#: steps). [choice] ±2 points of DSN success, ±1 step of its mean steps (the tables print
#: steps to two decimals, and runs differ by several), ±3 points of a match's win rate.
MARGINS = {"success_rate": 2.0, "mean_steps": 1.0, "win_rate": 3.0}
#: The field part's margins, by task family, for both its metrics (declared 2026-12-07
#: before any of its runs; [choice]): 0.05 of LBF's return (an episode earns at most 1;
#: the field study's seeds spread by 0.1-0.3 at a point), 3 of simple_spread's (its
#: returns lie between about -40 and -120; the study's seeds spread by 3-10).
FIELD_MARGINS = {"foraging": 0.05, "simple_spread": 3.0}
#: The deep learners each part compares (``--algorithms`` chooses among them).
DEEP = {
    "dsn": ("vdn", "qmix", "deep-cmarl-cd"),
    "tournament": ("vdn", "qmix"),
    "head-to-head": ("vdn", "qmix"),
    "field": ("deep-cmarl-cd",),
}
#: Each part's greedy evaluation episodes where ``--eval-episodes`` is not given.
EVAL_EPISODES = {"dsn": "10k", "tournament": "10k", "head-to-head": "10k", "field": "100"}


def step_settings(algorithms: list[str], step: str, design: str | None = None) -> str:
    """``--set``'s value that gives every learner of the study ``step`` (named, not left
    to the default, which may change: the study compares the two steps themselves), and
    with ``design`` deep CMARL-CD's design at the field's discount."""
    settings = [f"{name}.step={step}" for name in algorithms]
    if design is not None:
        settings += [f"deep-cmarl-cd.design={design}", "deep-cmarl-cd.gamma=0.99"]
    return ",".join(settings)


def command(part: str, args: argparse.Namespace, store: Path, fused: bool) -> list[str]:
    """The ``cmarl-cd`` command of one side of the study."""
    algorithms = ",".join(args.algorithms)
    design = None
    if part == "dsn":
        line = ["dsn", "--algorithms", algorithms, "--runs", str(args.runs)]
        line += ["--episodes", args.episodes, "--eval-episodes", args.eval_episodes]
    elif part == "field":
        line = ["field", "--tasks", args.tasks, "--learners", algorithms]
        line += ["--seeds", str(args.runs), "--steps", args.steps]
        line += ["--eval-interval", args.eval_interval, "--eval-episodes", args.eval_episodes]
        line += ["--inputs", "own-observations", "--no-progress"]
        design = args.design
    else:
        line = ["tournament", "--algorithms", algorithms, "--rounds", str(args.runs)]
        line += ["--learn-episodes", args.learn_episodes, "--eval-episodes", args.eval_episodes]
    line += ["--store", str(store), "--figures", str(store.parent / "figures")]
    line += ["--workers", str(args.workers)]
    step = "fused" if fused else "autograd"
    return [*line, "--set", step_settings(args.algorithms, step, design)]


def step_of(config: dict) -> str:
    """Which step a stored run's learners took: ``autograd`` (named, or left out of the
    identity as in runs stored before the setting), ``fused``, or ``other`` (``auto``,
    or the two mixed: not part of the study)."""
    learners = config.get("learners") or [config.get("learner", {})]
    steps = {learner.get("step", "autograd") for learner in learners}
    return steps.pop() if len(steps) == 1 and steps <= {"autograd", "fused"} else "other"


def samples(
    part: str, store: Path, first_run: int = 0
) -> dict[tuple[str, str], dict[str, list[float]]]:
    """(cell, metric) -> step -> one value per run (runs from index ``first_run`` on)."""
    out: dict = defaultdict(lambda: defaultdict(list))
    query = "SELECT experiment, algorithm, config, metrics, run_index FROM runs"
    with sqlite3.connect(f"file:{store}?mode=ro", uri=True) as conn:
        rows = conn.execute(query).fetchall()
    for experiment, algorithm, config_text, metrics_text, run_index in rows:
        config, metrics = json.loads(config_text), json.loads(metrics_text)
        field = part == "field" and config.get("unit") == "steps"
        if (experiment != part and not field) or run_index < first_run:
            continue
        step = step_of(config)
        if field:  # the experiment is the task's family
            returns = [point[2] for point in metrics["curve"]]
            cell = f"{experiment}:{config['game']['task']}"
            out[(cell, "average_return")][step].append(sum(returns) / len(returns))
            out[(cell, "final_return")][step].append(returns[-1])
        elif part == "dsn":
            for budget, values in metrics["checkpoints"].items():
                cell = f"{algorithm} L={int(budget):,}"
                out[(cell, "success_rate")][step].append(100 * values["success_rate"])
                out[(cell, "mean_steps")][step].append(values["mean_steps"])
        else:
            # the first-listed learner's position in this round (they alternate), so that
            # self-play measures one copy too
            wins = metrics["wins"][metrics["first_side"]]
            out[(algorithm, "win_rate")][step].append(100 * wins / metrics["episodes"])
    return out


def head_to_head_specs(args: argparse.Namespace) -> list:
    """The matches of each learner's fused step (listed first) against its autograd step."""
    from dataclasses import replace

    from cmarlcd.cli.options import parse_count
    from cmarlcd.experiments import tournament as tour
    from cmarlcd.runs import RunSpec

    learners = tour.battlefield_learners()
    learn = parse_count(args.learn_episodes, "learn-episodes")
    evaluate = parse_count(args.eval_episodes, "eval-episodes")
    specs = []
    for name in args.algorithms:
        pair = tuple(replace(learners[name], step=step) for step in ("fused", "autograd"))
        pairing = tour.Pairing(pair, learn, evaluate)
        label = f"{name} fused vs autograd"
        specs += [RunSpec.make(tour.EXPERIMENT, label, pairing, 0, r) for r in range(args.runs)]
    return specs


def compute_head_to_head(args: argparse.Namespace, store: Path) -> None:
    """Every match of :func:`head_to_head_specs` not yet stored (resumable), rounds learning
    together as the tournament's do."""
    from cmarlcd.experiments import tournament as tour
    from cmarlcd.sweeps.runner import run_sweep
    from cmarlcd.sweeps.store import ResultStore
    from cmarlcd.version import __version__

    with ResultStore(store) as db:
        done = run_sweep(
            head_to_head_specs(args), db, workers=args.workers, version=__version__,
            seed_batch=tour.SEED_BATCH, description="head-to-head",
        )  # fmt: skip
    print(f"head-to-head: {done.computed} matches computed", flush=True)


def head_to_head_samples(store: Path, first_run: int = 0) -> dict[str, tuple[list, list]]:
    """cell -> (each match's even split, the fused side's win rate), in points."""
    out: dict = defaultdict(lambda: ([], []))
    query = "SELECT algorithm, metrics, run_index FROM runs"
    with sqlite3.connect(f"file:{store}?mode=ro", uri=True) as conn:
        rows = conn.execute(query).fetchall()
    for algorithm, metrics_text, run_index in rows:
        if run_index < first_run:
            continue
        metrics = json.loads(metrics_text)
        episodes = metrics["episodes"]
        even, fused = out[algorithm]
        even.append(100 * (episodes - metrics["ties"]) / 2 / episodes)
        fused.append(100 * metrics["wins"][metrics["first_side"]] / episodes)
    return out


def report_head_to_head(store: Path, first_run: int = 0) -> list[dict]:
    """The paired TOST of every head-to-head cell, printed and returned."""
    results = []
    print(f"head-to-head: paired TOST at alpha = {ALPHA} (the fused side against the even split)")
    for cell, (even, fused) in sorted(head_to_head_samples(store, first_run).items()):
        if len(even) < 2:
            continue
        result = paired_tost(even, fused, MARGINS["win_rate"])
        verdict = "equivalent" if result.equivalent else "NOT shown equivalent"
        print(
            f"  {cell:26} even split {result.reference_mean:6.2f} fused side "
            f"{result.candidate_mean:6.2f}  difference {result.difference:+6.2f} "
            f"[{result.low:+6.2f}, {result.high:+6.2f}] within ±{result.margin:g}: "
            f"{verdict} (p = {result.p_value:.3g}; {result.reference_runs} matches)"
        )
        results.append({"cell": cell, "metric": "win_rate", **result.to_dict()})
    return results


def report(part: str, store: Path, first_run: int = 0) -> list[dict]:
    """The TOST of every cell, printed and returned."""
    if part == "head-to-head":
        return report_head_to_head(store, first_run)
    results = []
    since = f", runs {first_run} on" if first_run else ""
    print(f"{part}: TOST at alpha = {ALPHA} (a {100 * (1 - 2 * ALPHA):.0f} % interval{since})")
    for (cell, metric), by_step in sorted(samples(part, store, first_run).items()):
        if len(by_step.get("autograd", [])) < 2 or len(by_step.get("fused", [])) < 2:
            continue
        margin = FIELD_MARGINS[cell.split(":")[0]] if part == "field" else MARGINS[metric]
        result = tost(by_step["autograd"], by_step["fused"], margin)
        verdict = "equivalent" if result.equivalent else "NOT shown equivalent"
        print(
            f"  {cell:18} {metric:12} autograd {result.reference_mean:8.3f} "
            f"fused {result.candidate_mean:8.3f}  difference {result.difference:+7.3f} "
            f"[{result.low:+7.3f}, {result.high:+7.3f}] within ±{result.margin:g}: "
            f"{verdict} (p = {result.p_value:.3g}; {result.reference_runs} and "
            f"{result.candidate_runs} runs)"
        )
        results.append({"cell": cell, "metric": metric, **result.to_dict()})
    return results


def markdown(part: str, results: list[dict]) -> str:
    """The cells as a Markdown table (the docs' table of the study)."""
    sides = "even split | fused side" if part == "head-to-head" else "autograd | fused"
    lines = [
        f"| cell | metric | {sides} | difference [90 % interval] | margin | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    d = 3 if part == "field" else 2  # LBF's returns are at most 1
    for r in results:
        verdict = "**equivalent**" if r["equivalent"] else "not shown equivalent"
        lines.append(
            f"| {part} {r['cell']} | {r['metric'].replace('_', ' ')} | "
            f"{r['reference_mean']:.{d}f} | {r['candidate_mean']:.{d}f} | "
            f"{r['difference']:+.{d}f} [{r['low']:+.{d}f}, {r['high']:+.{d}f}] | "
            f"±{r['margin']:g} | {verdict} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=tuple(DEEP))
    parser.add_argument(
        "--algorithms",
        default="vdn,qmix",
        help="deep learners compared (DSN: vdn, qmix, deep-cmarl-cd; tournament: vdn, qmix; "
        "field: deep-cmarl-cd)",
    )
    parser.add_argument("--runs", type=int, default=50, help="runs (DSN) or rounds per cell")
    parser.add_argument("--episodes", default="100k", help="DSN learning budgets L")
    parser.add_argument("--learn-episodes", default="20k", help="tournament learning episodes")
    parser.add_argument(
        "--eval-episodes", help="greedy evaluation episodes (field: 100 per point; else 10k)"
    )
    parser.add_argument("--tasks", default="foraging:8x8-2p-2f-coop,simple_spread",
                        help="field: the compiled tasks")  # fmt: skip
    parser.add_argument("--steps", default="500k", help="field: environment steps a run")
    parser.add_argument("--eval-interval", default="50k",
                        help="field: steps between evaluations (the study's)")  # fmt: skip
    parser.add_argument("--design", default="shares-range-shared",
                        help="field: deep CMARL-CD's design")  # fmt: skip
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("results/equivalence"))
    parser.add_argument("--report-only", action="store_true", help="test what is stored")
    parser.add_argument("--markdown", action="store_true", help="also print a Markdown table")
    parser.add_argument(
        "--first-run",
        type=int,
        default=0,
        help="test only the runs (rounds) from this index on, e.g. the rounds a study "
        "added after a first look, as a confirmation of their own (written to "
        "PART-from-N.json)",
    )
    args = parser.parse_args(argv)
    if args.runs < 2:
        parser.error("--runs: at least 2 runs a side")
    if not 0 <= args.first_run < args.runs:
        parser.error("--first-run: from 0 to --runs - 1")
    if args.part == "field" and args.algorithms == parser.get_default("algorithms"):
        args.algorithms = "deep-cmarl-cd"
    if args.eval_episodes is None:
        args.eval_episodes = EVAL_EPISODES[args.part]
    args.algorithms = [name.strip() for name in args.algorithms.split(",") if name.strip()]
    unknown = sorted(set(args.algorithms) - set(DEEP[args.part]))
    if unknown or not args.algorithms:
        known = ", ".join(DEEP[args.part])
        parser.error(f"--algorithms: {args.part} compares {known} (got {', '.join(unknown)})")
    store = args.out / f"{args.part}.sqlite"
    if args.report_only and not store.is_file():
        parser.error(f"--report-only: no study stored at {store}")
    store.parent.mkdir(parents=True, exist_ok=True)
    if not args.report_only and args.part == "head-to-head":
        compute_head_to_head(args, store)
    elif not args.report_only:
        for fused in (False, True):
            line = command(args.part, args, store, fused)
            print("run: cmarl-cd " + " ".join(line), flush=True)
            done = subprocess.run([sys.executable, "-m", "cmarlcd", *line])
            if done.returncode:
                return done.returncode
    results = report(args.part, store, args.first_run)
    if args.markdown:
        print(markdown(args.part, results))
    name = f"{args.part}-from-{args.first_run}" if args.first_run else args.part
    (args.out / f"{name}.json").write_text(
        json.dumps({"margins": MARGINS, "alpha": ALPHA, "cells": results}, indent=1)
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
