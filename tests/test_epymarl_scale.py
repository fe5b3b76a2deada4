"""The conversion of simple_spread returns to the EPyMARL paper's scale
(benchmarks/epymarl_scale.py) holds episode by episode on the random policy."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).parents[1] / "benchmarks/epymarl_scale.py"


def test_the_conversion_holds_on_the_random_policy() -> None:
    pytest.importorskip("mpe2")
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--episodes", "20"], capture_output=True, text=True,
        check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    assert "largest per-episode difference" in done.stdout


def test_bad_episodes_are_one_line() -> None:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--episodes", "0"], capture_output=True, text=True,
        check=False,
    )  # fmt: skip
    assert done.returncode == 2 and done.stderr.strip() == "error: --episodes must be >= 1"
