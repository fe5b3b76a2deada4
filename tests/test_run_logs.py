"""Live curves (``--log-dir``): each run's scalars read back with TensorBoard's own
reader equal its CSV, a run killed and computed again writes no point twice, a torn CSV
line is cut, and a missing writer is one line."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cmarlcd.run_logs import CSV_NAME, RunLog, log_point, logging_runs

ROOT = Path(__file__).resolve().parents[1]
event_accumulator = pytest.importorskip("tensorboard.backend.event_processing.event_accumulator")


def cli(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cmarlcd", *args], capture_output=True,
                          text=True, timeout=600, cwd=ROOT, **kwargs)  # fmt: skip


def events(folder: Path) -> dict[tuple[str, int], list[float]]:
    """Every scalar of the folder's event files, as TensorBoard reads them."""
    found: dict[tuple[str, int], list[float]] = {}
    for path in sorted(folder.glob("events.out.tfevents.*")):
        reader = event_accumulator.EventAccumulator(str(path))
        reader.Reload()
        for tag in reader.Tags()["scalars"]:
            for event in reader.Scalars(tag):
                found.setdefault((tag, event.step), []).append(event.value)
    return found


def rows(folder: Path) -> list[dict[str, str]]:
    with (folder / CSV_NAME).open() as table:
        return list(csv.DictReader(table))


def test_a_deep_run_writes_its_curve_loss_epsilon_and_rate(tmp_path) -> None:
    pytest.importorskip("torch")
    logs = tmp_path / "logs"
    done = cli("train", "--game", "simple_spread:N=3", "--algorithms", "vdn", "--steps", "1000",
               "--runs", "2", "--curve-points", "5", "--workers", "1", "--no-progress",
               "--store", str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"),
               "--log-dir", str(logs))  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    folders = sorted(logs.iterdir())
    assert [f.name.split("-")[:4] for f in folders] == [
        ["simple_spread", "vdn", "seed0", "run0"],
        ["simple_spread", "vdn", "seed0", "run1"],
    ]
    for folder in folders:
        table = rows(folder)
        written = {(r["tag"], int(r["step"])): float(r["value"]) for r in table}
        assert len(written) == len(table)  # no point twice
        read = events(folder)
        assert set(read) == set(written)
        for key, values in read.items():  # TensorBoard keeps float32
            assert values == [np.float32(written[key])]
        steps = sorted({s for tag, s in written if tag == "eval/return"})
        assert steps == [200, 400, 600, 800, 1000]
        for tag in ("train/epsilon", "rate/steps_per_second", "eval/success"):
            assert {s for t, s in written if t == tag} == set(steps)
        assert {s for t, s in written if t == "train/loss"}  # a gradient step was taken
        epsilons = [written["train/epsilon", s] for s in steps]
        assert epsilons == sorted(epsilons, reverse=True) and epsilons[0] < 1.0
    stored = cli("report", "--store", str(tmp_path / "s.sqlite"), "--format", "json")
    assert stored.returncode == 0


def test_a_run_killed_and_computed_again_writes_no_point_twice(tmp_path) -> None:
    """kill -9 while the run is writing its curve; the command again (the run starts
    over from its seeds): every point once, in the CSV and in the event files."""
    logs, store = tmp_path / "logs", tmp_path / "s.sqlite"
    args = ("dsn", "--algorithms", "cmarl-cd", "--episodes", "400k", "--runs", "1",
            "--workers", "1", "--no-progress", "--store", str(store), "--figures",
            str(tmp_path / "f"), "--log-dir", str(logs))  # fmt: skip
    started = subprocess.Popen([sys.executable, "-m", "cmarlcd", *args], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               start_new_session=True)  # fmt: skip
    deadline = time.time() + 300
    while time.time() < deadline:
        tables = list(logs.glob(f"*/{CSV_NAME}"))
        if tables and sum(1 for _ in tables[0].open()) > 8:  # a few points written
            break
        time.sleep(0.2)
    os.killpg(started.pid, signal.SIGKILL)
    started.wait()
    before = len(rows(next(logs.iterdir())))
    assert before >= 8
    done = cli(*args)
    assert done.returncode == 0, done.stderr[-3000:]
    folder = next(logs.iterdir())
    table = rows(folder)
    keys = [(r["tag"], int(r["step"])) for r in table]
    assert len(keys) == len(set(keys)) > before
    assert {k: len(v) for k, v in events(folder).items()} == dict.fromkeys(keys, 1)


def test_a_torn_last_line_is_cut_and_written_again(tmp_path) -> None:
    with logging_runs([str(tmp_path)]):
        log_point(0, 10, {"eval/return": 1.5}, "episodes")
        log_point(0, 20, {"eval/return": 2.5}, "episodes")
    table = tmp_path / CSV_NAME
    text = table.read_text()
    # killed while writing the return at step 20, in the middle of its value (the cut is
    # found by the row's start: a later rate or wall time may also hold the digits "2.5")
    row = text.index("20,eval/return,2.5")
    table.write_text(text[: row + len("20,eval/return,2")])
    log = RunLog(tmp_path)
    assert ("eval/return", 10) in log.written and ("eval/return", 20) not in log.written
    log.scalars(20, {"eval/return": 2.5}, "episodes")
    log.close()
    values = [(r["step"], r["value"]) for r in rows(tmp_path) if r["tag"] == "eval/return"]
    assert values == [("10", "1.5"), ("20", "2.5")]


def test_no_run_writes_where_none_asked_and_others_are_untouched(tmp_path) -> None:
    with logging_runs([None, str(tmp_path / "b")]):
        log_point(0, 1, {"eval/return": 1.0}, "episodes")
        log_point(1, 1, {"eval/return": 2.0, "train/loss": None}, "episodes")
        log_point(2, 1, {"eval/return": 3.0}, "episodes")  # no such run: nothing
    log_point(1, 2, {"eval/return": 4.0}, "episodes")  # after the runs: nothing
    assert [p.name for p in tmp_path.iterdir()] == ["b"]
    written = [(r["tag"], r["value"]) for r in rows(tmp_path / "b")]
    assert ("eval/return", "2.0") in written and "train/loss" not in dict(written)
    assert "4.0" not in dict(written).values()


def test_log_dir_without_the_writer_is_one_line(tmp_path) -> None:
    blocked = ("import sys; sys.modules['tensorboard'] = None; sys.argv[0] = 'cmarl-cd'; "
               "from cmarlcd.cli import app; app()")  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-c", blocked, "repeated", "--runs", "1", "--store",
         str(tmp_path / "s.sqlite"), "--log-dir", str(tmp_path / "logs")],
        capture_output=True, text=True, timeout=300, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "error: --log-dir: writes TensorBoard logs with the tensorboard package: "
        "pip install 'cmarl-cd[logs]'"
    )
    assert not (tmp_path / "s.sqlite").exists() and not (tmp_path / "logs").exists()


@pytest.mark.parametrize(
    ("command", "tags"),
    [
        (("repeated", "--runs", "2"), {"eval/greedy_payoff", "eval/success"}),
        (("compare", "--games", "climbing", "--learners", "cmarl-cd", "--runs", "2"),
         {"eval/greedy_payoff", "eval/optimal"}),
        (("tournament", "--algorithms", "cmarl-cd,la-oca", "--rounds", "1",
          "--learn-episodes", "50", "--eval-episodes", "20"),
         {"eval/win_rate_side0", "eval/win_rate_side1", "eval/ties"}),
    ],
)  # fmt: skip
def test_runs_without_a_curve_write_their_outcome(tmp_path, command, tags) -> None:
    done = cli(*command, "--workers", "1", "--no-progress", "--store",
               str(tmp_path / "s.sqlite"), "--figures", str(tmp_path / "f"), "--log-dir",
               str(tmp_path / "logs"))  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    folders = list((tmp_path / "logs").iterdir())
    assert folders
    for folder in folders:
        assert {r["tag"] for r in rows(folder)} - {"rate/episodes_per_second"} == tags
