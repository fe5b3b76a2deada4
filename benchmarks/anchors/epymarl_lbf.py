"""The outside anchor on Level-Based Foraging: EPyMARL's IQL, VDN and QMIX beside cmarl-cd's.

EPyMARL (uoe-agents/epymarl at commit cbc38c0, the study that fixed the protocol the field
reports) runs its own ``src/main.py`` with its own configs (``--config=iql|vdn|qmix
--env-config=gymma``, ``env_args.time_limit=50`` as its README gives for LBF, lbforaging
2.0.0's ``Foraging-TASK-v3``); cmarl-cd runs ``cmarl-cd field`` on its compiled copy of
the same task (``foraging:TASK``, checked step for step against lbforaging 2.0.0) with
EPyMARL's settings (``--preset epymarl``), each agent reading its own observation as
EPyMARL's agents do. Both sides learn for the same budget of environment steps and
evaluate greedily over the same number of episodes at the same interval, starting before
learning (EPyMARL tests after its first episode, at step 50, then at the first episode
end past each interval; cmarl-cd at 0 and every interval: the k-th points are compared).

For each task and algorithm the script prints both sides' maximum and average return with
their 95 % intervals over the seeds (:mod:`cmarlcd.experiments.field_metrics`), whether
ours lies within EPyMARL's interval of the maximum or above it, and steps a second on each
side with the load the machine ran under; ``OUT/anchor.json``, ``OUT/anchor.md`` and
``OUT/anchor.png`` (the curves) come from whatever runs are done.

EPyMARL is not on PyPI: give the path of a checkout of cbc38c0 (``git clone
https://github.com/uoe-agents/epymarl && git -C epymarl checkout cbc38c0``). Its
environment: ``bash benchmarks/anchors/install.sh epymarl``. EPyMARL imports SMAClite and
torch_scatter at start for environments and algorithms this anchor never runs (SMAClite
installs only from GitHub, torch_scatter only by compiling against torch); the script puts
empty stand-ins for the two first on EPyMARL's path, which raise if anything of theirs is
called. Each EPyMARL run (one process, one core, as EPyMARL sets ``torch`` to one thread)
and each task's cmarl-cd command is one job, written under ``OUT`` as it ends, so an
interrupted anchor resumes where it stopped; the logs are kept in ``OUT/logs``.

    python benchmarks/anchors/epymarl_lbf.py --epymarl ~/epymarl --steps 1M --seeds 3
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

#: EPyMARL's algorithms and cmarl-cd's learner of each (cmarl-cd's ``iql`` is tabular).
ALGORITHMS = {"iql": "deep-iql", "vdn": "vdn", "qmix": "qmix"}
TASKS = ("8x8-2p-2f-coop", "10x10-3p-3f")
COMMIT = "cbc38c0"
#: EPyMARL's README: every LBF task with ``env_args.time_limit=50`` (lbforaging's own cap).
TIME_LIMIT = 50
#: Modules EPyMARL imports at start but the anchor never uses: empty stand-ins.
STAND_INS = {
    "smaclite": '"""Stand-in: the LBF anchor runs no SMAClite map."""\n',
    "torch_scatter": '"""Stand-in: the LBF anchor runs no PAC-DCG."""\n\n\n'
    "def scatter_add(*args, **kwargs):\n"
    '    raise RuntimeError("torch_scatter stand-in: not for PAC-DCG")\n',
}
SIDES = ("cmarl-cd", "epymarl")
#: EPyMARL's agent networks: ``rnn``, its configs as they are (``use_rnn: True``, a GRU
#: for the second layer); ``mlp``, the same configs with ``use_rnn=False`` (a ReLU layer
#: there: a feed-forward network of two hidden layers); ``one-layer``, the same with one
#: hidden layer, cmarl-cd's model class (``epymarl_agents.py`` adds it to EPyMARL's
#: registry and launches EPyMARL's ``src/main.py``).
AGENTS = {
    "rnn": (),
    "mlp": ("use_rnn=False",),
    "one-layer": ("use_rnn=False", "agent=one_layer"),
}
#: The launcher of the agents EPyMARL's tree lacks (``--agent one-layer``).
LAUNCHER = Path(__file__).with_name("epymarl_agents.py")
#: cmarl-cd's agent networks: ``shared``, one network for every agent with the agent's
#: one-hot index in its input (``share=true``, as EPyMARL's configs), or ``per-agent``,
#: one network an agent (the preset's; the anchor's jobs before ``share`` existed).
OURS = ("shared", "per-agent")
#: cmarl-cd's gradient steps (``DeepConfig.step``): ``auto`` leaves the learners' default
#: (autograd's for shared or deeper networks), ``fused`` the compiled step, equal to
#: autograd's per step to float32 rounding (its tests), several times faster.
STEPS = ("auto", "fused", "autograd")


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        protocol = check(args)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    out = Path(args.out)
    if args.speed:
        return speed(protocol, out, args)
    if not args.report_only:
        for side in protocol["sides"]:
            run_jobs(side, jobs(side, protocol), protocol, out, args)
    summary = summarise(out, protocol)
    name = "-".join(["anchor", *(() if protocol["agent"] == "rnn" else (protocol["agent"],)),
                     *(() if protocol["ours"] == "shared" else (protocol["ours"],)),
                     *layers_tag(protocol)])  # fmt: skip
    write(out / f"{name}.json", summary)
    (out / f"{name}.md").write_text(table(summary) + "\n")
    figure(summary, out / f"{name}.png")
    print(table(summary))
    return 0


def speed(protocol: dict, out: Path, args: argparse.Namespace) -> int:
    """``--speed``: both sides' steps a second in turns (``epymarl_speed.py``)."""
    sys.path.insert(0, str(Path(__file__).parent))
    from epymarl_speed import measure, speed_table

    result = measure(sys.modules[__name__], protocol, Path(args.epymarl), out, args.rounds,
                     args.any_commit)  # fmt: skip
    name = "-".join(["speed", protocol["tasks"][0], protocol["agent"], protocol["ours"],
                     *layers_tag(protocol)])  # fmt: skip
    write(out / f"{name}.json", result)
    (out / f"{name}.md").write_text(speed_table(result) + "\n")
    print(speed_table(result))
    return 0


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--epymarl", help="path of a checkout of EPyMARL at commit cbc38c0")
    p.add_argument("--tasks", default=",".join(TASKS), help="LBF tasks, comma list")
    p.add_argument("--algorithms", default=",".join(ALGORITHMS), help="iql, vdn, qmix")
    p.add_argument("--seeds", type=int, default=3, help="runs per task and algorithm")
    p.add_argument("--steps", default="1M", help="environment steps a run")
    p.add_argument("--eval-interval", default="50k", help="steps between greedy tests")
    p.add_argument("--eval-episodes", default="100", help="episodes a greedy test")
    p.add_argument("--sides", default=",".join(SIDES), help="which sides to compute")
    p.add_argument("--agent", default="rnn", help="EPyMARL's agents: rnn (its configs: a "
                   "GRU), mlp (use_rnn=False: feed-forward, two hidden layers) or one-layer "
                   "(feed-forward, one hidden layer: cmarl-cd's model class)")  # fmt: skip
    p.add_argument("--ours", default="shared", help="cmarl-cd's agents: shared (one "
                   "network, the agent's id in its input) or per-agent")  # fmt: skip
    p.add_argument("--layers", type=int, default=1, help="cmarl-cd's hidden layers an agent "
                   "network (2: EPyMARL's feed-forward agent, as --agent mlp)")  # fmt: skip
    p.add_argument("--hypernet-layers", type=int, default=1, help="cmarl-cd QMIX's "
                   "hypernetwork layers (2: EPyMARL's hypernet_layers)")  # fmt: skip
    p.add_argument("--step", default="auto", help="cmarl-cd's gradient step: auto (the "
                   "learner's default), fused or autograd")  # fmt: skip
    p.add_argument("--out", default="results/anchor-epymarl", help="where runs are kept")
    p.add_argument("--any-commit", action="store_true", help="allow another EPyMARL commit")
    p.add_argument("--parallel", type=int, default=1, help="EPyMARL runs at a time (one "
                   "core each)")  # fmt: skip
    p.add_argument("--report-only", action="store_true", help="compute nothing, report")
    p.add_argument("--speed", action="store_true", help="measure only steps a second: each "
                   "algorithm's EPyMARL run and cmarl-cd command in turns on the first task, "
                   "--steps each, under the same load")  # fmt: skip
    p.add_argument("--rounds", type=int, default=3, help="(--speed) turns of each side")
    return p


def count(text: str, name: str) -> int:
    """``"1M"`` -> 1000000, ``"50k"`` -> 50000."""
    scale = {"k": 1_000, "m": 1_000_000}.get(text[-1:].lower(), 1)
    try:
        value = round(float(text[:-1] if scale > 1 else text) * scale)
    except ValueError:
        raise ValueError(f"--{name}: not a count: {text!r}") from None
    if value < 1:
        raise ValueError(f"--{name}: must be >= 1 (got {text})")
    return value


def check(args: argparse.Namespace) -> dict[str, Any]:
    """The protocol of the anchor, or one ValueError naming what is wrong."""
    from cmarlcd.errors import ConfigError
    from cmarlcd.experiments import games

    tasks = [t.strip() for t in args.tasks.split(",") if t.strip()]
    for task in tasks:
        try:
            games.parse_game(f"foraging:{task}")
        except ConfigError as error:
            raise ValueError(f"--tasks: {task}: {error.message}") from None
    algorithms = [a.strip() for a in args.algorithms.split(",") if a.strip()]
    for algorithm in algorithms:
        if algorithm not in ALGORITHMS:
            raise ValueError(f"--algorithms: unknown {algorithm!r} (one of iql, vdn, qmix)")
    sides = [s.strip() for s in args.sides.split(",") if s.strip()]
    for side in sides:
        if side not in SIDES:
            raise ValueError(f"--sides: unknown {side!r} (one of {', '.join(SIDES)})")
    if args.rounds < 1:
        raise ValueError(f"--rounds: must be >= 1 (got {args.rounds})")
    if args.speed and args.report_only:
        raise ValueError("--speed computes; --report-only computes nothing: give one")
    if args.parallel < 1:
        raise ValueError(f"--parallel: must be >= 1 (got {args.parallel})")
    if args.layers < 1:
        raise ValueError(f"--layers: must be >= 1 (got {args.layers})")
    if args.hypernet_layers not in (1, 2):
        raise ValueError(f"--hypernet-layers: must be 1 or 2 (got {args.hypernet_layers})")
    if args.step not in STEPS:
        raise ValueError(f"--step: unknown {args.step!r} (one of {', '.join(STEPS)})")
    if args.ours not in OURS:
        raise ValueError(f"--ours: unknown {args.ours!r} (one of {', '.join(OURS)})")
    if args.agent not in AGENTS:
        raise ValueError(f"--agent: unknown {args.agent!r} (one of {', '.join(AGENTS)})")
    if not (tasks and algorithms and sides) or args.seeds < 1:
        raise ValueError("needs a task, an algorithm, a side and --seeds >= 1")
    steps, interval = count(args.steps, "steps"), count(args.eval_interval, "eval-interval")
    if steps % interval:
        raise ValueError(f"--eval-interval must divide --steps (got {interval} and {steps})")
    if args.speed or ("epymarl" in sides and not args.report_only):
        checkout_commit(args.epymarl, args.any_commit)
    protocol = {"tasks": tasks, "algorithms": algorithms, "sides": sides, "seeds": args.seeds,
                "agent": args.agent, "ours": args.ours, "layers": args.layers,
                "hypernet_layers": args.hypernet_layers, "step": args.step}  # fmt: skip
    episodes = count(args.eval_episodes, "eval-episodes")
    return {**protocol, "steps": steps, "eval_interval": interval, "eval_episodes": episodes}


def checkout_commit(path: str | None, any_commit: bool) -> str:
    """The EPyMARL checkout's commit, checked."""
    if not path:
        raise ValueError("--epymarl: give the path of a checkout of EPyMARL at cbc38c0")
    if not (Path(path) / "src" / "main.py").is_file():
        raise ValueError(f"--epymarl: {path} holds no src/main.py: not an EPyMARL checkout")
    done = subprocess.run(
        ["git", "-C", path, "rev-parse", "HEAD"], capture_output=True, text=True, check=False
    )
    commit = done.stdout.strip() or "unknown (not a git checkout)"
    if not commit.startswith(COMMIT) and not any_commit:
        raise ValueError(f"--epymarl: {path} is at {commit[:12]}, not {COMMIT} (--any-commit)")
    return commit


def jobs(side: str, protocol: dict) -> list[tuple]:
    if side == "cmarl-cd":  # one command per task: its learners' seeds stacked
        return [cmarlcd_job(task, protocol) for task in protocol["tasks"]]
    return [
        epymarl_job(task, algorithm, seed, protocol)
        for seed in range(protocol["seeds"])  # seed 0 of every pair first
        for task in protocol["tasks"]
        for algorithm in protocol["algorithms"]
    ]


def cmarlcd_job(task: str, protocol: dict) -> tuple:
    """cmarl-cd's job on a task: ``(task, "shared")`` where its agents share one network
    (as EPyMARL's configs), ``(task,)`` where each has its own (the jobs before ``share``
    existed); ``layersN`` after it where its networks have N > 1 hidden layers."""
    base = (task, "shared") if protocol["ours"] == "shared" else (task,)
    return (*base, *layers_tag(protocol))


def layers_tag(protocol: dict) -> tuple[str, ...]:
    """``"layersN"`` where cmarl-cd's agent networks have N > 1 hidden layers,
    ``"hyper2"`` where its QMIX's hypernetworks have two, and the step where it is named
    (``fused``, ``autograd``; none for the learners' default)."""
    layers, step = protocol.get("layers", 1), protocol.get("step", "auto")
    return (*(() if layers == 1 else (f"layers{layers}",)),
            *(("hyper2",) if protocol.get("hypernet_layers", 1) == 2 else ()),
            *(() if step == "auto" else (step,)))  # fmt: skip


def epymarl_job(task: str, algorithm: str, seed: int, protocol: dict) -> tuple:
    """An EPyMARL run: its configs' GRU agents keep the jobs' first names."""
    agent = protocol["agent"]
    return (task, algorithm, seed) if agent == "rnn" else (task, algorithm, seed, agent)


def job_path(out: Path, side: str, job: tuple) -> Path:
    return out / side / ("-".join(map(str, job)) + ".json")


def run_jobs(side: str, todo: list[tuple], protocol: dict, out: Path, args) -> None:
    """The side's jobs, ``--parallel`` at a time (each EPyMARL run takes one core), in
    order; the first that fails ends the anchor once those under way have ended."""
    if args.parallel == 1:
        for job in todo:
            run_job(side, job, protocol, out, args)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=args.parallel) as pool:
        futures = [pool.submit(run_job, side, job, protocol, out, args) for job in todo]
        for future in futures:
            future.result()


def run_job(side: str, job: tuple, protocol: dict, out: Path, args: argparse.Namespace) -> None:
    path = job_path(out, side, job)
    if load(path, protocol, side):
        return
    (out / "logs").mkdir(parents=True, exist_ok=True)
    log = out / "logs" / f"{side}-{'-'.join(map(str, job))}.log"
    print(f"[{time.strftime('%H:%M:%S')}] {side} {' '.join(map(str, job))} (log: {log})")
    before = os.getloadavg()
    start = time.perf_counter()
    if side == "cmarl-cd":
        result = ours(job[0], protocol, out, log)
    else:
        result = epymarl(*job[:3], protocol, Path(args.epymarl), log, args.any_commit)
    seconds = time.perf_counter() - start
    write(path, {
        "side": side, "job": list(job), "protocol": protocol_of(protocol, side),
        "seconds": seconds, "load": {"before": before, "after": os.getloadavg()},
        "machine": machine(), **result,
    })  # fmt: skip


def protocol_of(protocol: dict, side: str) -> dict:
    """What a job's numbers depend on: an EPyMARL run on the budget and the tests, a
    cmarl-cd command on its seeds and learners too (not on which tasks a call computes)."""
    keys = ["steps", "eval_interval", "eval_episodes"]
    if side == "cmarl-cd":
        return {**{k: protocol[k] for k in keys}, "seeds": protocol["seeds"],
                "algorithms": sorted(protocol["algorithms"])}  # fmt: skip
    return {k: protocol[k] for k in keys}


def machine() -> dict[str, Any]:
    return {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
            "python": platform.python_version(), "torch": version("torch"),
            "lbforaging": version("lbforaging"), "cmarl-cd": version("cmarl-cd")}  # fmt: skip


def version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


def ours(task: str, protocol: dict, out: Path, log: Path) -> dict[str, Any]:
    """``cmarl-cd field`` on the task: every learner and seed, one worker."""
    learners = ",".join(ALGORITHMS[a] for a in protocol["algorithms"])
    settings = [
        f"{ALGORITHMS[a]}.{s}"
        for a in protocol["algorithms"]
        for s in [
            *(("share=true",) if protocol["ours"] == "shared" else ()),
            *((f"hidden_layers={protocol['layers']}",) if protocol.get("layers", 1) > 1 else ()),
            *(("hypernet_layers=2",) if a == "qmix" and protocol.get("hypernet_layers", 1) == 2
              else ()),
            *((f"step={protocol['step']}",) if protocol.get("step", "auto") != "auto" else ()),
        ]
    ]  # fmt: skip
    command = [
        "field", "--tasks", f"foraging:{task}", "--learners", learners, "--preset", "epymarl",
        *(("--set", ",".join(settings)) if settings else ()),
        "--inputs", "own-observations", "--seeds", str(protocol["seeds"]),
        "--steps", str(protocol["steps"]), "--eval-interval", str(protocol["eval_interval"]),
        "--eval-episodes", str(protocol["eval_episodes"]), "--workers", "1", "--no-progress",
        "--store", str(out / "cmarl-cd.sqlite"), "--figures", str(out / "figures"), "--json",
    ]  # fmt: skip
    with log.open("w") as errors:
        done = subprocess.run(
            [sys.executable, "-m", "cmarlcd", *command], stdout=subprocess.PIPE,
            stderr=errors, text=True, check=False,
        )  # fmt: skip
    if done.returncode != 0:
        raise SystemExit(f"error: cmarl-cd field failed on {task}: see {log}")
    (doc,) = json.loads(done.stdout)["tasks"]
    curves = {a: [[p[1] for p in run] for run in doc["curves"][label(a, doc)]]
              for a in protocol["algorithms"]}  # fmt: skip
    return {"command": "cmarl-cd " + " ".join(command), "curves": curves, "computed": True}


def label(algorithm: str, doc: dict) -> str:
    """The row of ``algorithm`` in the field's document (named for the preset)."""
    name = {"iql": "Deep IQL", "vdn": "VDN", "qmix": "QMIX"}[algorithm]
    (found,) = [k for k in doc["curves"] if k.split(" (")[0] == name]
    return found


def epymarl(
    task: str, algorithm: str, seed: int, protocol: dict, path: Path, log: Path, any_commit: bool
) -> dict[str, Any]:
    """One EPyMARL run with its own configs; its greedy tests read from sacred's record."""
    stand_ins = log.parent / "stand-ins"
    for module, text in STAND_INS.items():
        (stand_ins / module).mkdir(parents=True, exist_ok=True)
        (stand_ins / module / "__init__.py").write_text(text)
    key = f"lbforaging:Foraging-{task}-v3"
    tag = f"cmarlcd-anchor-{task}-{algorithm}-{seed}-{time.time_ns()}"
    launcher = (str(LAUNCHER.resolve()),) if protocol["agent"] == "one-layer" else ()
    command = [
        sys.executable, *launcher, "src/main.py", f"--config={algorithm}",
        "--env-config=gymma", "with",
        f"env_args.time_limit={TIME_LIMIT}", f"env_args.key={key}", f"seed={seed}",
        f"t_max={protocol['steps']}", f"test_interval={protocol['eval_interval']}",
        f"log_interval={protocol['eval_interval']}", f"test_nepisode={protocol['eval_episodes']}",
        "use_cuda=False", "save_model=False", f"label={tag}", *AGENTS[protocol["agent"]],
    ]  # fmt: skip
    environment = {**os.environ, "PYTHONPATH": str(stand_ins.resolve())}
    with log.open("w") as output:
        done = subprocess.run(
            command, cwd=path, env=environment, stdout=output, stderr=subprocess.STDOUT,
            check=False,
        )  # fmt: skip
    if done.returncode != 0:
        raise SystemExit(f"error: EPyMARL failed on {task} {algorithm} seed {seed}: see {log}")
    record = sacred_record(path / "results" / "sacred" / algorithm / key, tag)
    info = json.loads((record / "info.json").read_text())
    returns = [value(v) for v in info["test_return_mean"]]
    trained = info["test_return_mean_T"][-1]  # the steps done at the last test
    return {
        "command": " ".join(command[1:]), "commit": checkout_commit(str(path), any_commit),
        "record": str(record), "curve": [list(p) for p in zip(info["test_return_mean_T"],
                                                            returns, strict=True)],
        "steps_trained": trained,
    }  # fmt: skip


def sacred_record(folder: Path, tag: str) -> Path:
    """The sacred run folder whose config carries ``tag`` as its label."""
    for config in folder.glob("*/config.json"):
        if json.loads(config.read_text()).get("label") == tag:
            return config.parent
    raise SystemExit(f"error: no sacred record labelled {tag} under {folder}")


def value(entry: Any) -> float:
    """A number as sacred's jsonpickle keeps it (``{"py/object": ..., "value": x}``)."""
    return float(entry["value"] if isinstance(entry, dict) else entry)


# ----------------------------------------------------------------------------- report


def summarise(out: Path, protocol: dict) -> dict[str, Any]:
    """Per task and algorithm, each side's figures from the runs done so far."""
    from cmarlcd.experiments.field_metrics import field_metrics

    points = protocol["steps"] // protocol["eval_interval"] + 1
    nominal = [k * protocol["eval_interval"] for k in range(points)]
    pairs, rates = [], {"cmarl-cd": [], "epymarl": []}
    for task in protocol["tasks"]:
        mine = load(job_path(out, "cmarl-cd", cmarlcd_job(task, protocol)), protocol, "cmarl-cd")
        if mine:
            seeds = protocol["seeds"] * len(protocol["algorithms"])
            rates["cmarl-cd"].append(seeds * protocol["steps"] / mine["seconds"])
        for algorithm in protocol["algorithms"]:
            theirs = [load(job_path(out, "epymarl", epymarl_job(task, algorithm, s, protocol)),
                           protocol, "epymarl") for s in range(protocol["seeds"])]  # fmt: skip
            theirs = [r for r in theirs if r]
            rates["epymarl"] += [r["steps_trained"] / r["seconds"] for r in theirs]
            row: dict[str, Any] = {"task": task, "algorithm": algorithm}
            if mine:
                row["cmarl-cd"] = field_metrics(nominal, mine["curves"][algorithm]).as_dict()
            if theirs:
                shortest = min(len(r["curve"]) for r in theirs)  # tests at episode ends
                curves = [[p[1] for p in r["curve"][:shortest]] for r in theirs]
                row["epymarl"] = field_metrics(nominal[:shortest], curves).as_dict()
                row["epymarl_curve_steps"] = theirs[0]["curve"][:shortest]
            if mine and len(theirs) == protocol["seeds"]:
                ours_max, low = row["cmarl-cd"]["max_return"], row["epymarl"]["max_return_low"]
                row["verdict"] = "within or above" if ours_max >= low else "below"
            elif mine and theirs:  # an interval over fewer seeds judges nothing yet
                row["verdict"] = f"not yet ({len(theirs)} of {protocol['seeds']} EPyMARL seeds)"
            row["curves"] = {"cmarl-cd": mine["curves"][algorithm] if mine else [],
                             "epymarl": [[p[1] for p in r["curve"]] for r in theirs]}  # fmt: skip
            pairs.append(row)
    mean = {side: sum(r) / len(r) if r else None for side, r in rates.items()}
    ratio = mean["cmarl-cd"] / mean["epymarl"] if all(mean.values()) else None
    return {"protocol": protocol, "points": nominal, "pairs": pairs,
            "steps_per_second": mean, "ratio": ratio, "commit": COMMIT}  # fmt: skip


def load(path: Path, protocol: dict, side: str) -> dict | None:
    """A finished job of this protocol, or None."""
    if not path.exists():
        return None
    data = json.loads(path.read_text())
    return data if data["protocol"] == protocol_of(protocol, side) else None


def table(summary: dict) -> str:
    def cell(figures: dict | None, key: str) -> str:
        if not figures:
            return "–"
        low, high = figures[f"{key}_low"], figures[f"{key}_high"]
        return f"{figures[key]:.3f} [{low:.3f}, {high:.3f}]"

    p = summary["protocol"]
    lines = [
        f"EPyMARL {COMMIT} ({p['agent']} agents) and cmarl-cd ({p['ours']} agents, "
        f"{p.get('layers', 1)} hidden layer{'s' if p.get('layers', 1) > 1 else ''}"
        f"{'' if p.get('step', 'auto') == 'auto' else ', the ' + p['step'] + ' step'}) on LBF: "
        f"{p['steps']:,} steps, {p['seeds']} seeds, "
        f"{p['eval_episodes']} greedy episodes every {p['eval_interval']:,} steps",
        "",
        "| task | algorithm | max return, EPyMARL | max return, cmarl-cd | average, EPyMARL "
        "| average, cmarl-cd | cmarl-cd's maximum |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in summary["pairs"]:
        theirs, mine = row.get("epymarl"), row.get("cmarl-cd")
        lines.append(
            f"| {row['task']} | {row['algorithm']} | {cell(theirs, 'max_return')} | "
            f"{cell(mine, 'max_return')} | {cell(theirs, 'average_return')} | "
            f"{cell(mine, 'average_return')} | {row.get('verdict', 'not yet')} |"
        )
    rates = summary["steps_per_second"]
    said = {side: f"{rate:,.0f}" if rate else "–" for side, rate in rates.items()}
    ratio = f"{summary['ratio']:.1f}x" if summary["ratio"] else "–"
    lines += ["", f"Steps a second on one core: EPyMARL {said['epymarl']} a run, cmarl-cd "
              f"{said['cmarl-cd']} (every learner and seed of a task); ratio {ratio}."]  # fmt: skip
    return "\n".join(lines)


def figure(summary: dict, path: Path) -> None:
    """One panel per task: each algorithm's mean curve over seeds, both sides."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    tasks = summary["protocol"]["tasks"]
    fig, axes = plt.subplots(1, len(tasks), figsize=(5.5 * len(tasks), 4), squeeze=False)
    colours = dict(zip(ALGORITHMS, ("tab:blue", "tab:orange", "tab:green"), strict=True))
    for ax, task in zip(axes[0], tasks, strict=True):
        for row in (r for r in summary["pairs"] if r["task"] == task):
            for side, style in (("epymarl", "--"), ("cmarl-cd", "-")):
                runs = row["curves"][side]
                if not runs:
                    continue
                shortest = min(len(r) for r in runs)
                mean = np.mean([r[:shortest] for r in runs], axis=0)
                x = np.array(summary["points"][:shortest]) / 1e6
                name = f"{row['algorithm']}, {'EPyMARL' if side == 'epymarl' else 'cmarl-cd'}"
                ax.plot(x, mean, style, color=colours[row["algorithm"]], label=name)
        ax.set(title=f"LBF {task}", xlabel="environment steps (millions)",
               ylabel="greedy return (mean over seeds)")  # fmt: skip
        if ax.get_legend_handles_labels()[0]:  # nothing done yet: no legend
            ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(path: Path, data: dict) -> None:
    """Written whole or not at all."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(f".{os.getpid()}.part")
    partial.write_text(json.dumps(data, indent=1))
    os.replace(partial, path)


if __name__ == "__main__":
    sys.exit(main())
