"""Which CPU-dependent kernel moves a run's numbers: one fixed-seed command computed again
with each library told to compute as another CPU would, on this one machine.

A seed fixes a run bit for bit on one machine and one set of library versions. Across
machines, what a library compiles or dispatches for the CPU at hand may round otherwise:

* ``torch``: PyTorch picks its CPU kernels by the instruction set it finds
  (``ATEN_CPU_CAPABILITY``: ``default``, ``avx2``, ``avx512``), and oneMKL its own
  (``MKL_ENABLE_INSTRUCTIONS``);
* ``numba``: it compiles for this host's CPU (``NUMBA_CPU_NAME``, ``NUMBA_CPU_FEATURES``):
  another CPU can give the fused step's reassociated sums another vector width, and
  fused multiply-adds where this one has none.

Each variant runs the command in a fresh process and store (numba's cache in a folder of
its own, so nothing compiled for one variant is read by another) and prints each
learner's mean return and its spread over the runs; a row that differs from the
baseline's names the library whose CPU path the learner's numbers depend on.

Usage: python benchmarks/seed_portability.py [--episodes 3000] [--runs 2] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: Each variant: the environment it adds to the baseline's.
VARIANTS: dict[str, dict[str, str]] = {
    "baseline (this CPU)": {},
    "torch: no vector kernels": {"ATEN_CPU_CAPABILITY": "default"},
    "oneMKL: SSE4.2 only": {"MKL_ENABLE_INSTRUCTIONS": "SSE4_2"},
    "numba: a generic x86-64": {"NUMBA_CPU_NAME": "generic", "NUMBA_CPU_FEATURES": ""},
    "numba: no FMA": {"NUMBA_CPU_NAME": "x86-64-v2", "NUMBA_CPU_FEATURES": ""},
}


def rows(args: argparse.Namespace, extra: dict[str, str]) -> dict[str, list[float]]:
    """Each learner's mean return and spread from one fresh computation."""
    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, **extra, "NUMBA_CACHE_DIR": str(Path(folder) / "numba")}
        command = [sys.executable, "-m", "cmarlcd", "dsn", "--algorithms", args.algorithms,
                   "--episodes", str(args.episodes), "--runs", str(args.runs),
                   "--eval-episodes", str(args.eval_episodes), "--seed", str(args.seed),
                   "--workers", "1", "--no-progress", "--json",
                   "--store", str(Path(folder) / "s.sqlite"),
                   "--figures", str(Path(folder) / "f")]  # fmt: skip
        done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    doc = json.loads(done.stdout)
    found = {}
    for row in doc["rows"]:
        found[row["algorithm"]] = [row["mean_return"], row["std_return"]]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algorithms", default="vdn,qmix,deep-cmarl-cd,cmarl-cd")
    parser.add_argument("--episodes", type=int, default=3000)
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--eval-episodes", type=int, default=500)
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    found = {name: rows(args, extra) for name, extra in VARIANTS.items()}
    if args.json:
        print(json.dumps(found, indent=2))
        return
    base = found["baseline (this CPU)"]
    for name, table in found.items():
        said = ", ".join(
            f"{learner} {mean:.3f} (std {std:.3f}){'' if [mean, std] == base[learner] else ' *'}"
            for learner, (mean, std) in table.items()
        )
        print(f"{name}: {said}")
    print("*: differs from the baseline, bit for bit")


if __name__ == "__main__":
    main()
