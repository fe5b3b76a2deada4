"""Benchmark: one fixed sweep on every backend, with 1 and 2 workers.

Two sweeps, each computed into a fresh store:

* **long runs**: 12 DSN runs of CMARL-CD and LA-OCA (500k learning episodes each), about
  a second a run: how well the backends scale;
* **short runs**: 400 runs of Table 2's smallest cells, a few milliseconds a run: what a
  backend costs per run.

For each backend and worker count it prints the wall time, the speed-up over one worker
in this process (the baseline, measured in the same run), the efficiency (speed-up /
workers) and the overhead per run: (wall - Σ run seconds / workers) / runs. Ray runs on
a local Ray started before the clock (its start-up is timed on its own line), twice:
*cold*, as a command's first sweep finds it (Ray's worker processes start and load
cmarl-cd), then *warm*, the same sweep again on the same workers.

**Worker start-up**: the seconds from a sweep's first task to every one of its local
workers ready to compute (the DSN's kernels loaded), for workers that come from the fork
server (*cold*: the command's first sweep, which starts the server, imports the package
and loads the kernels from numba's cache; *warm*: a later sweep of the same command) and,
measured in the same run, the baseline of 0.6.0, workers forked from the sweep's own
process after it loaded the kernels itself (which is unsafe with threads running), and
spawned workers (where the system has no fork server), each loading everything itself.

Usage: python benchmarks/bench_backends.py [--json] [--startup-only]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import platform
import tempfile
import time
from multiprocessing import forkserver
from pathlib import Path

from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments.sensor_network import DsnSweep
from cmarlcd.registry import LEARNERS
from cmarlcd.sweeps.backends import local
from cmarlcd.sweeps.backends.tasks import warm_up
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore

LONG = DsnSweep(
    learners=(LEARNERS["cmarl-cd"], LEARNERS["la-oca"]),
    episodes=(500_000,),
    runs=6,
    eval_episodes=5_000,
    seed=7,
).specs()
SHORT = rep.RepeatedSweep(case=2, agents=(4,), actions=(3, 4), runs=200, seed=7).specs()


def timed_sweep(specs: list, backend: str, workers: int) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as tmp, ResultStore(Path(tmp) / "b.sqlite") as store:
        start = time.perf_counter()
        done = run_sweep(specs, store, workers=workers, backend=backend)
        wall = time.perf_counter() - start
    compute = sum(done.run_seconds)
    return {
        "runs": len(specs),
        "wall_seconds": wall,
        "overhead_ms_per_run": 1000 * (wall - compute / workers) / len(specs),
    }


def measure(name: str, specs: list, ray: object | None) -> list[dict]:
    rows = []
    for workers in (1, 2):
        row = {"sweep": name, "backend": "process", "workers": workers}
        rows.append({**row, **timed_sweep(specs, "process", workers)})
    for workers in (1, 2) if ray is not None else ():
        ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        # cold: Ray's worker processes start, import cmarl-cd and load the compiled
        # kernels; warm: the same sweep again (into a fresh store) on those workers
        for state in ("ray cold", "ray warm"):
            row = {"sweep": name, "backend": state, "workers": workers}
            rows.append({**row, **timed_sweep(specs, "ray", workers)})
        ray.shutdown()
    base = rows[0]["wall_seconds"]
    for row in rows:
        row["speedup"] = base / row["wall_seconds"]
        row["efficiency"] = row["speedup"] / row["workers"]
    return rows


def ready_seconds(workers: int) -> float:
    """Seconds from the first task to ``workers`` local workers all ready."""
    backend = local.ProcessBackend(workers, lambda *_: None)
    backend.prepare(LONG[:1])
    start = time.perf_counter()
    backend._start()
    while not all(worker.ready for worker in backend.workers):
        backend.poll(0.01)
    seconds = time.perf_counter() - start
    backend.close(cancel=False)
    return seconds


def _stop_fork_server() -> None:
    forkserver._forkserver._stop()
    local._server = local._Server()


def _forked_ready(conn) -> None:
    conn.send("ready")


def forked_seconds(workers: int) -> tuple[float, float]:
    """0.6.0's baseline: the kernels loaded in this process, then ``workers`` forks of it
    ready; the two times."""
    start = time.perf_counter()
    warm_up(LONG[:1])
    loaded = time.perf_counter() - start
    context = multiprocessing.get_context("fork")
    start = time.perf_counter()
    pipes, processes = [], []
    for _ in range(workers):
        ours, theirs = context.Pipe()
        processes.append(context.Process(target=_forked_ready, args=(theirs,)))
        processes[-1].start()
        pipes.append(ours)
    for pipe in pipes:
        pipe.recv()
    seconds = time.perf_counter() - start
    for process in processes:
        process.join()
    return loaded, seconds


def startup_rows(workers: int = 2) -> list[dict]:
    """Worker start-up, each way, ``workers`` workers (the kernels in numba's cache)."""
    rows = []
    _stop_fork_server()
    rows.append({"start": "fork server, cold", "seconds": ready_seconds(workers)})
    rows.append({"start": "fork server, warm", "seconds": ready_seconds(workers)})
    original = local.worker_context
    local.worker_context = lambda warm, deep: multiprocessing.get_context("spawn")
    try:
        rows.append({"start": "spawn", "seconds": ready_seconds(workers)})
    finally:
        local.worker_context = original
    loaded, forked = forked_seconds(workers)
    rows.append({"start": "0.6.0: fork, kernels loaded first", "seconds": loaded + forked})
    rows.append({"start": "0.6.0: fork alone", "seconds": forked})
    for row in rows:
        row["workers"] = workers
        row["per_worker_seconds"] = row["seconds"] / workers
    return rows


def ray_startup(ray: object) -> float:
    start = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    seconds = time.perf_counter() - start
    ray.shutdown()
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--startup-only", action="store_true", help="only worker start-up")
    args = parser.parse_args()
    try:
        import ray
    except ImportError:
        ray = None
    # compile once, outside the clock (every backend loads the same cached kernels)
    timed_sweep(LONG[:1] + SHORT[:1], "process", 1)
    starts = startup_rows()
    rows = (
        []
        if args.startup_only
        else measure("long runs", LONG, ray) + measure("short runs", SHORT, ray)
    )
    startup = ray_startup(ray) if ray is not None and not args.startup_only else None
    if args.json:
        print(
            json.dumps({"rows": rows, "ray_startup_seconds": startup, "workers": starts}, indent=2)
        )
        return
    print(f"{platform.processor() or platform.machine()}, {platform.python_version()}")
    print("worker start-up, 2 workers (the DSN's kernels in numba's cache):")
    for r in starts:
        print(
            f"  {r['start']:36} {r['seconds']:6.2f} s  ({r['per_worker_seconds']:.3f} s a worker)"
        )
    print(f"{'sweep':11} {'backend':9} {'workers':>7} {'runs':>5} {'wall s':>8} "
          f"{'speed-up':>8} {'effic.':>6} {'overhead ms/run':>15}")  # fmt: skip
    for r in rows:
        print(f"{r['sweep']:11} {r['backend']:9} {r['workers']:>7} {r['runs']:>5} "
              f"{r['wall_seconds']:>8.2f} {r['speedup']:>7.2f}x {r['efficiency']:>6.2f} "
              f"{r['overhead_ms_per_run']:>15.2f}")  # fmt: skip
    if args.startup_only:
        return
    if startup is not None:
        print(f"starting a local Ray of 2 CPUs: {startup:.1f} s (paid once per command)")
    else:
        print("Ray is not installed (pip install 'cmarl-cd[ray]'): its rows are left out")


if __name__ == "__main__":
    main()
