"""Where a run was computed (beyond the paper): the versions of the package and of the
libraries whose code computes its numbers, and the machine, recorded beside every run
stored (:meth:`cmarlcd.sweeps.store.ResultStore.put`) so that a reader who reruns a
stored command and gets another number can tell a different machine from a fault.

A seed fixes a run bit for bit on the same machine and versions. Across machines it
fixes what is computed with integer or exactly rounded arithmetic, and may not fix what
numba or PyTorch compile for the CPU at hand: the compiler targets ``cpu_target`` (its
instruction set, ``isa_level``), and a fused multiply-add or a vectorised reduction
rounds differently from two operations, so a float that decides a tie can differ in its
last bit (see the docs' "What a seed fixes").
"""

from __future__ import annotations

import functools
import importlib.metadata
import platform
from pathlib import Path
from typing import Any

#: The libraries whose code computes a run's numbers (torch: where installed).
LIBRARIES = ("numpy", "numba", "llvmlite", "torch")
#: x86-64 microarchitecture levels by the features each adds (psABI), lowest first.
X86_LEVELS = (
    ("x86-64-v2", ("cx16", "lahf_lm|sahf", "popcnt", "sse3", "sse4.1", "sse4.2", "ssse3")),
    ("x86-64-v3", ("avx", "avx2", "bmi|bmi1", "bmi2", "f16c", "fma", "lzcnt|abm", "movbe")),
    ("x86-64-v4", ("avx512f", "avx512bw", "avx512cd", "avx512dq", "avx512vl")),
)


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def cpu_model() -> str:
    """The CPU's model name (Linux's ``/proc/cpuinfo``), else the platform's word."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def isa_level(features: set[str], machine: str) -> str:
    """The highest x86-64 level whose every feature the CPU has (``machine`` otherwise)."""
    if machine.lower() not in ("x86_64", "amd64"):
        return machine
    level = "x86-64"
    for name, needed in X86_LEVELS:
        if not all(any(f in features for f in need.split("|")) for need in needed):
            break
        level = name
    return level


def compiler_target() -> tuple[str, set[str]]:
    """The CPU numba compiles for (LLVM's name of this host) and its features."""
    import llvmlite.binding as llvm

    features = {name.lstrip("+") for name, on in llvm.get_host_cpu_features().items() if on}
    return str(llvm.get_host_cpu_name()), features


@functools.cache
def current() -> dict[str, Any]:
    """This process's provenance: versions, Python, the CPU and what numba targets."""
    from cmarlcd.version import __version__

    target, features = compiler_target()
    return {
        "cmarl_cd": __version__,
        "python": platform.python_version(),
        **{name: _version(name) for name in LIBRARIES},
        "cpu": cpu_model(),
        "cpu_target": target,
        "isa_level": isa_level(features, platform.machine()),
        "system": f"{platform.system()} {platform.machine()}",
    }


def describe(info: dict[str, Any]) -> str:
    """One line: ``cmarl-cd 0.7.0, Python 3.11.7, numpy 2.4.6, ..., AMD EPYC (znver3,
    x86-64-v3)``."""
    libraries = ", ".join(f"{name} {info[name]}" for name in LIBRARIES if info.get(name))
    where = f"{info.get('cpu')} ({info.get('cpu_target')}, {info.get('isa_level')})"
    device = f", device {info['device']}" if info.get("device") else ""
    return (f"cmarl-cd {info.get('cmarl_cd')}, Python {info.get('python')}, {libraries}, "
            f"{where}{device}")  # fmt: skip


def places(
    found: list[tuple[dict[str, Any] | None, int]],
) -> list[tuple[dict[str, Any] | None, int]]:
    """``found`` with the records that agree wherever both say something merged (a
    table run records no torch, a deep run of the same machine does)."""
    merged: list[tuple[dict[str, Any] | None, int]] = []
    for info, n in found:
        for k, (place, count) in enumerate(merged):
            if (
                info is not None
                and place is not None
                and all(
                    place.get(key) is None or info.get(key) is None or place[key] == info[key]
                    for key in {*place, *info}
                )
            ):
                both = {key: place.get(key) or info.get(key) for key in {*place, *info}}
                merged[k] = (both, count + n)
                break
        else:
            merged.append((info, n))
    return merged


def store_lines(found: list[tuple[dict[str, Any] | None, int]]) -> list[str]:
    """What a report says of a store's provenances (:meth:`ResultStore.provenances`):
    one line where every run was computed alike, else one per place and what differs."""
    alike = places(found)
    said = [
        (f"{n} runs: " if len(alike) > 1 else "computed with ")
        + ("no provenance recorded (stored before it was)" if info is None else describe(info))
        for info, n in alike
    ]
    if len(alike) <= 1:
        return said
    known = [info for info, _ in alike if info is not None]
    differ = sorted({k for info in known for k in info if len({str(i.get(k)) for i in known}) > 1})
    head = "runs of this store were computed in different places"
    head += f" (they differ in {', '.join(differ)}):" if differ else ":"
    return [head, *("  " + line for line in said)]


def as_json(found: list[tuple[dict[str, Any] | None, int]]) -> list[dict[str, Any]]:
    """The store's provenances for a JSON report: each with its number of runs."""
    return [{"runs": n, **(info or {"recorded": False})} for info, n in found]
