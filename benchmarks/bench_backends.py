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

Usage: python benchmarks/bench_backends.py [--json]
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments.sensor_network import DsnSweep
from cmarlcd.registry import LEARNERS
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


def ray_startup(ray: object) -> float:
    start = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    seconds = time.perf_counter() - start
    ray.shutdown()
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    try:
        import ray
    except ImportError:
        ray = None
    # compile once, outside the clock (every backend loads the same cached kernels)
    timed_sweep(LONG[:1] + SHORT[:1], "process", 1)
    rows = measure("long runs", LONG, ray) + measure("short runs", SHORT, ray)
    startup = ray_startup(ray) if ray is not None else None
    if args.json:
        print(json.dumps({"rows": rows, "ray_startup_seconds": startup}, indent=2))
        return
    print(f"{platform.processor() or platform.machine()}, {platform.python_version()}")
    print(f"{'sweep':11} {'backend':9} {'workers':>7} {'runs':>5} {'wall s':>8} "
          f"{'speed-up':>8} {'effic.':>6} {'overhead ms/run':>15}")  # fmt: skip
    for r in rows:
        print(f"{r['sweep']:11} {r['backend']:9} {r['workers']:>7} {r['runs']:>5} "
              f"{r['wall_seconds']:>8.2f} {r['speedup']:>7.2f}x {r['efficiency']:>6.2f} "
              f"{r['overhead_ms_per_run']:>15.2f}")  # fmt: skip
    if startup is not None:
        print(f"starting a local Ray of 2 CPUs: {startup:.1f} s (paid once per command)")
    else:
        print("Ray is not installed (pip install 'cmarl-cd[ray]'): its rows are left out")


if __name__ == "__main__":
    main()
