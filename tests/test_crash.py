"""The crash test (benchmarks/crash_test.py) on a small budget: a sweep killed with
SIGKILL at random moments and resumed ends with the uninterrupted sweep's store."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # kills and resumes real sweeps

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "crash_test.py"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_sweep_killed_and_resumed_three_times_stores_each_run_once(tmp_path) -> None:
    command = [
        sys.executable,
        str(SCRIPT),
        "--sweep",
        "dsn",
        "--kills",
        "3",
        "--dir",
        str(tmp_path),
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "PASS: 3 kills" in done.stdout and "FAIL" not in done.stdout
