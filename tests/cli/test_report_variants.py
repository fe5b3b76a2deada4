"""Runs of two settings of one learner never share a cell of a report: two sweeps on
one store that differ in one learner setting (``--set``) give two rows (or two
tournaments), each named with its setting, in every format ``report`` writes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.common import invoke

pytestmark = pytest.mark.slow  # two sweeps and four reports per experiment

#: Each experiment's command and a tiny budget; the two sweeps differ in CMARL-CD's delta.
SWEEPS = {
    "dsn": "dsn --algorithms cmarl-cd --episodes 300 --runs 2 --eval-episodes 20",
    "tournament": "tournament --algorithms cmarl-cd,la-oca --rounds 2 --learn-episodes 200 "
    "--eval-episodes 50",
    "scaling": "scaling --sizes 2x3/2 --algorithms cmarl-cd --episodes 300 --runs 2 "
    "--eval-episodes 20",
    "train": "train --env cmarlcd.games.sensor_network:SensorNetworkEnv --algorithms cmarl-cd "
    "--episodes 100 --runs 2 --eval-episodes 5 --curve-points 2",
}
DELTAS = ("0.02", "0.08")


def cli(*args: str) -> subprocess.CompletedProcess:
    done = subprocess.run(
        [sys.executable, "-m", "cmarlcd", *args], capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return done


@pytest.mark.parametrize("experiment", list(SWEEPS))
def test_two_settings_are_two_rows_in_every_format(tmp_path: Path, experiment: str) -> None:
    where = ["--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "figures")]
    for delta in DELTAS:
        settings = ["--set", f"cmarl-cd.delta={delta}", "--workers", "1", "--no-progress"]
        cli(*SWEEPS[experiment].split(), *settings, *where)
    labels = [f"CMARL-CD (delta={delta})" for delta in DELTAS]
    for fmt in ("text", "markdown", "html", "json"):
        shown = invoke("report", "--format", fmt, *where).stdout
        for label in labels:
            assert label in shown, f"{fmt}: {label} missing"
        assert "CMARL-CD *" not in shown
    sections = json.loads(invoke("report", "--json", *where).stdout)[experiment]
    stored = sum(sum(section["versions"].values()) for section in sections)
    assert stored >= 4  # both sweeps' runs reported (one was left out before)
    text = json.dumps(sections)
    assert all(label in text for label in labels)
