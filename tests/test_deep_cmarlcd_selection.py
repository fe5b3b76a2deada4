"""The declared selection run's script (benchmarks/deep_cmarlcd_selection.sh): each design
runs at its settings written out (a design by name is ``design=NAME``, the learner's own
list), and an unknown name is one line and status 2 before any run starts."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "benchmarks/deep_cmarlcd_selection.sh"


def selection(tmp_path: Path, *designs: str) -> subprocess.CompletedProcess:
    """The script with ``python -m cmarlcd`` recorded, not run (``python -c`` runs)."""
    stub = tmp_path / "bin"
    stub.mkdir(exist_ok=True)
    python = stub / "python"
    python.write_text(
        f'#!/bin/bash\n[ "$1" = -c ] && exec {sys.executable} "$@"\n'
        f'echo "$@" >> {tmp_path / "calls"}\n'
    )
    python.chmod(0o755)
    env = {**os.environ, "PATH": f"{stub}:{os.environ['PATH']}"}
    return subprocess.run(
        ["bash", str(SCRIPT), str(tmp_path / "out"), *designs],
        capture_output=True, text=True, env=env, check=False, cwd=ROOT,
    )  # fmt: skip


def settings(call: str) -> str:
    words = call.split()
    return words[words.index("--set") + 1]


def test_each_design_runs_at_its_settings(tmp_path: Path) -> None:
    done = selection(tmp_path, "shares-range-bootstrap-shared-slow", "critic-sum", "keyed")
    assert done.returncode == 0, done.stderr
    calls = (tmp_path / "calls").read_text().splitlines()
    d = "deep-cmarl-cd"
    assert [settings(c) for c in calls] == [
        f"{d}.design=shares-range-bootstrap-shared-slow,{d}.gamma=0.99",
        f"{d}.design=critic,{d}.critic_form=sum,{d}.gamma=0.99",
        f"{d}.gamma=0.99",
    ]
    assert all("--steps 500k --seeds 3" in c for c in calls)


def test_an_unknown_design_stops_before_any_run(tmp_path: Path) -> None:
    done = selection(tmp_path, "shares-cold", "shares-colder")
    assert done.returncode == 2
    line = done.stderr.strip()
    assert line.startswith("error: unknown design 'shares-colder' (keyed ")
    assert "shares-cold " in line and "\n" not in line
    assert not (tmp_path / "calls").exists() and not (tmp_path / "out").exists()
