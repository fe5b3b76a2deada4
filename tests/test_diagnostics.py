"""The diagnostic scripts of ``benchmarks/`` as a user runs them: a report on a tiny
budget, and bad input refused in one line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")

MEMORY = Path(__file__).parents[1] / "benchmarks/deep_cmarlcd_memory.py"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(MEMORY), *args], capture_output=True, text=True, check=False
    )


def test_the_memory_diagnostic_reports_each_checkpoint() -> None:
    """On a small LBF task every first visit is a record (``first-visit``): the memory
    keeps states from the first episode on, and each row's shares are shares."""
    done = run("foraging:5x5-2p-1f", "--steps", "2k", "--checkpoints", "2",
               "--set", "unseen_record=first-visit")  # fmt: skip
    assert done.returncode == 0, done.stderr
    header, *rows = done.stdout.strip().splitlines()
    assert header.startswith("steps | kept | records > 0")
    assert [r.split(" | ")[0] for r in rows] == ["0", "1,000", "2,000"]
    last = rows[-1].split(" | ")
    assert int(last[1].replace(",", "")) > 0
    assert 0 <= float(last[2]) <= 1 and 0 <= float(last[3]) <= 1


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["foraging:9x9"], "not a foraging task"),
        (["foraging:5x5-2p-1f", "--set", "bogus=1"], "no setting 'bogus'"),
        (["foraging:5x5-2p-1f", "--steps", "2k", "--checkpoints", "0"], "--checkpoints"),
    ],
)
def test_the_memory_diagnostic_refuses_bad_input_in_one_line(args, says) -> None:
    done = run(*args)
    assert done.returncode == 2
    assert says in done.stderr and done.stderr.count("\n") == 1, done.stderr


CRITIC = Path(__file__).parents[1] / "benchmarks/deep_cmarlcd_critic.py"


def critic(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(CRITIC), *args], capture_output=True, text=True, check=False
    )


def test_the_critic_diagnostic_reads_the_ring_the_critic_and_the_degrees() -> None:
    done = critic("foraging:5x5-2p-1f", "--steps", "3k", "--set", "batch_size=64")
    assert done.returncode == 0, done.stderr
    lines = dict(line.split(": ", 1) for line in done.stdout.strip().splitlines())
    assert lines["visits read"].startswith("3,0")  # every visit of 3k steps, at most 4,000
    assert "of 36" in lines["a*"]  # 6 × 6 joint actions
    share = float(lines["degrees' greedy joint action = a*"].rstrip("%"))
    assert 0 <= share <= 100


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["foraging:5x5-2p-1f", "--set", "update=replayed"], "reads the critic"),
        (["foraging:10x10-5p-3f"], "more than 4096"),
        (["foraging:5x5-2p-1f", "--set", "critic_fit=max"], "critic_fit"),
    ],
)
def test_the_critic_diagnostic_refuses_bad_input_in_one_line(args, says) -> None:
    done = critic(*args)
    assert done.returncode == 2
    assert says in done.stderr and done.stderr.count("\n") == 1, done.stderr
