"""Deep CMARL-CD's designs at the field protocol beside the study's columns
(benchmarks/deep_cmarlcd_designs_field.py): a hand-built report's figures land in their
design's column, each row's best in bold; bad input is one line and status 2."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "benchmarks/deep_cmarlcd_designs_field.py"
sys.path.insert(0, str(SCRIPT.parent))
spec = importlib.util.spec_from_file_location("deep_cmarlcd_designs_field", SCRIPT)
assert spec is not None and spec.loader is not None
designs = importlib.util.module_from_spec(spec)
spec.loader.exec_module(designs)


def figures(best: float) -> dict[str, float]:
    return {"max_return": best, "max_return_low": best - 0.1, "max_return_high": best + 0.1,
            "average_return": best / 2, "average_return_low": float("nan"),
            "average_return_high": float("nan")}  # fmt: skip


DESIGN_REPORT = {
    "train": [
        {"game": "foraging:8x8-2p-2f-coop", "field": {"Deep CMARL-CD (a=1)": figures(0.3)}},
        {"game": "foraging:5x5-2p-1f", "field": {"Deep CMARL-CD (a=1)": figures(0.9)}},
        {"game": "simple_spread:N=3,local_ratio=0.5,max_cycles=25",
         "field": {"random policy": figures(-79.0), "Deep CMARL-CD (a=1)": figures(-50.0)}},
    ]
}  # fmt: skip


def test_a_designs_store_gives_its_column(monkeypatch) -> None:
    monkeypatch.setattr(designs, "read", lambda store: DESIGN_REPORT)
    found = designs.design_figures(Path("any"))
    # a task outside the study is left out; simple_spread is found by its stored name
    assert list(found) == ["foraging:8x8-2p-2f-coop", "simple_spread"]
    assert found["simple_spread"]["max_return"] == -50.0
    columns = {
        "VDN": {"foraging:8x8-2p-2f-coop": figures(0.5)},
        "design": found,
    }
    lines = designs.table(columns, "max_return")
    assert lines[0] == "| task | VDN | design |"
    assert lines[2] == "| 8x8-2p-2f-coop | **0.500** [0.400, 0.600] | 0.300 [0.200, 0.400] |"
    assert lines[3] == "| simple_spread | – | **-50.000** [-50.100, -49.900] |"


def test_a_baselines_store_gives_its_learners_column(monkeypatch) -> None:
    report = {
        "train": [
            {"game": "foraging:8x8-2p-2f-coop",
             "field": {"random policy": figures(0.005), "VDN (EPyMARL, share=True)": figures(0.7),
                       "Deep CMARL-CD (a=1)": figures(0.3)}},
        ]
    }  # fmt: skip
    monkeypatch.setattr(designs, "read", lambda store: report)
    baseline = designs.design_figures(Path("any"), deep_cmarlcd=False)
    assert baseline["foraging:8x8-2p-2f-coop"]["max_return"] == 0.7  # not the floor's
    assert designs.design_figures(Path("any"))["foraging:8x8-2p-2f-coop"]["max_return"] == 0.3


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, check=False
    )


def test_a_column_without_figures_is_left_out() -> None:
    columns = {"VDN": {"simple_spread": figures(-40.0)}, "not computed": {},
               "design": {"simple_spread": figures(-30.0)}}  # fmt: skip
    header, _, row = designs.table(columns, "max_return")
    assert header == "| task | VDN | design |"
    assert row == "| simple_spread | -40.000 [-40.100, -39.900] | **-30.000** [-30.100, -29.900] |"


def test_bad_input_is_one_line(tmp_path: Path) -> None:
    done = run("--study", str(tmp_path / "absent.sqlite"))
    assert done.returncode == 2 and done.stderr.strip() == (
        f"error: no store at {tmp_path / 'absent.sqlite'}"
    )
    done = run("--study", str(tmp_path / "absent.sqlite"), "--design", "x")
    assert (
        done.returncode == 2 and done.stderr.strip() == "error: --design takes NAME=STORE (got 'x')"
    )
    done = run("--study", str(tmp_path / "absent.sqlite"), "--baseline", "=s")
    assert done.returncode == 2
    assert done.stderr.strip() == "error: --baseline takes NAME=STORE (got '=s')"
    text = tmp_path / "text.sqlite"
    text.write_text("not a store")
    done = run("--study", str(text))
    assert done.returncode == 2 and done.stderr.strip().startswith("error: --store:")


def test_the_design_script_refuses_missing_arguments_and_unknown_designs(tmp_path: Path) -> None:
    """benchmarks/deep_cmarlcd_design_field.sh: a usage line without a design and a store;
    a design that does not exist refused by the field command, before anything runs."""
    shell = ROOT / "benchmarks/deep_cmarlcd_design_field.sh"
    done = subprocess.run(["bash", str(shell)], capture_output=True, text=True, check=False)
    assert done.returncode == 2 and done.stderr.strip().startswith("usage:")
    store = tmp_path / "designs" / "s.sqlite"
    done = subprocess.run(
        ["bash", str(shell), "sharez", str(store), "simple_spread"],
        capture_output=True, text=True, check=False,
        env={**os.environ, "PYTHONPATH": str(ROOT / "src")},
    )  # fmt: skip
    assert done.returncode == 2
    assert "error: --set: deep-cmarl-cd has no design 'sharez'" in done.stderr
    assert not store.exists()


def recorded_field_calls(tmp_path: Path, *command: str, **env: str) -> list[list[str]]:
    """The ``python -m cmarlcd field`` calls a script makes, recorded, not run."""
    stub = tmp_path / "bin"
    stub.mkdir(exist_ok=True)
    (stub / "python").write_text(f'#!/bin/bash\necho "$@" >> {tmp_path / "calls"}\n')
    (stub / "python").chmod(0o755)
    path = {"PATH": f"{stub}:{os.environ['PATH']}"}
    done = subprocess.run(
        ["bash", *command], capture_output=True, text=True, check=False,
        env={**os.environ, **path, **env}, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    calls = [line.split() for line in (tmp_path / "calls").read_text().splitlines()]
    (tmp_path / "calls").unlink()
    return calls


def test_a_design_runs_at_the_studys_protocol_on_its_tasks(tmp_path: Path) -> None:
    """A design's store holds the study's runs of it: the same tasks, budget, seeds,
    evaluations and inputs as the field study's own deep CMARL-CD parts."""

    def protocol(call: list[str]) -> dict[str, str]:
        options: dict[str, str] = {}
        for word, following in zip(call[3:], [*call[4:], "--"], strict=True):
            if word.startswith("--"):  # an option and its value, or a flag
                options[word] = "" if following.startswith("--") else following
        return {k: v for k, v in options.items() if k not in ("--set", "--store", "--figures")}

    (design,) = recorded_field_calls(
        tmp_path, str(ROOT / "benchmarks/deep_cmarlcd_design_field.sh"),
        "shares-range-shared-refresh-slow-td-standardised", str(tmp_path / "d.sqlite"),
        STEP="fused",
    )  # fmt: skip
    (study,) = recorded_field_calls(
        tmp_path, str(ROOT / "benchmarks/field_study.sh"), "full", str(tmp_path / "study"),
        PARTS="shares",
    )  # fmt: skip
    assert design[:3] == study[:3] == ["-m", "cmarlcd", "field"]
    assert protocol(design) == protocol(study)
    assert protocol(design)["--steps"] == "2.05M" and protocol(design)["--seeds"] == "5"
    assert len(protocol(design)["--tasks"].split(",")) == 8
    # the same settings (their order is not part of a run's identity): the study's design
    # column is the design script's store, which `cmarl-cd merge` joins to the study's
    settings = [set(call[call.index("--set") + 1].split(",")) for call in (design, study)]
    assert settings[0] == settings[1]


def script_refusal(script: str, args: list[str], **env: str) -> str:
    """Run a study script as a user would with ``env`` set; it must refuse with status 2,
    and its one line of error is returned."""
    done = subprocess.run(
        ["bash", script, *args], capture_output=True, text=True, check=False,
        env={**os.environ, **env},
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    return done.stderr.strip()


def test_a_design_reads_the_time_left_where_told(tmp_path: Path) -> None:
    script = str(ROOT / "benchmarks/deep_cmarlcd_design_field.sh")
    store = str(tmp_path / "d.sqlite")
    (plain,) = recorded_field_calls(tmp_path, script, "shares-cold-shared", store)
    (timed,) = recorded_field_calls(tmp_path, script, "shares-cold-shared", store, TIME_LEFT="1")
    assert "--time-left" not in plain
    assert [w for w in timed if w != "--time-left"] == plain and "--time-left" in timed
    refused = script_refusal(script, ["shares-cold-shared", store], TIME_LEFT="yes")
    assert refused == "error: TIME_LEFT must be 0 or 1 (got 'yes')"


def test_a_design_takes_the_step_it_is_told(tmp_path: Path) -> None:
    """STEP=fused sets deep CMARL-CD's gradient step, nothing else changed; without STEP
    the settings are the design's as stored; another value is refused in one line."""
    script = str(ROOT / "benchmarks/deep_cmarlcd_design_field.sh")
    store = str(tmp_path / "d.sqlite")
    (plain,) = recorded_field_calls(tmp_path, script, "shares-cold-shared", store)
    (fused,) = recorded_field_calls(tmp_path, script, "shares-cold-shared", store, STEP="fused")
    at = plain.index("--set") + 1
    assert "step" not in plain[at]
    assert fused[at] == plain[at] + ",deep-cmarl-cd.step=fused"
    assert fused[:at] + fused[at + 1 :] == plain[:at] + plain[at + 1 :]
    refused = script_refusal(script, ["shares-cold-shared", store], STEP="fast")
    assert refused == "error: STEP must be auto, fused or autograd (got 'fast')"


def test_the_study_reads_the_time_left_where_told(tmp_path: Path) -> None:
    """TIME_LEFT=1 gives every part of the study the input, nothing else changed."""
    script = str(ROOT / "benchmarks/field_study.sh")
    out = str(tmp_path / "study")
    plain = recorded_field_calls(tmp_path, script, "full", out, PARTS="vdn shares")
    timed = recorded_field_calls(tmp_path, script, "full", out, PARTS="vdn shares", TIME_LEFT="1")
    assert len(plain) == len(timed) == 2
    for a, b in zip(plain, timed, strict=True):
        assert "--time-left" not in a and [w for w in b if w != "--time-left"] == a


def test_the_study_trains_seeds_apart_where_told(tmp_path: Path) -> None:
    """SEED_BATCH=1 gives every part ``--seed-batch 1`` (each seed trained and stored on
    its own), nothing else changed; unset, the command's default; 0 or a word refused."""
    script = str(ROOT / "benchmarks/field_study.sh")
    out = str(tmp_path / "study")
    plain = recorded_field_calls(tmp_path, script, "full", out, PARTS="deep-iql vdn")
    apart = recorded_field_calls(tmp_path, script, "full", out, PARTS="deep-iql vdn",
                                 SEED_BATCH="1")  # fmt: skip
    assert len(plain) == len(apart) == 2
    for a, b in zip(plain, apart, strict=True):
        assert "--seed-batch" not in a
        at = b.index("--seed-batch")
        assert b[at + 1] == "1" and b[:at] + b[at + 2 :] == a
    for bad in ("0", "one"):
        refused = script_refusal(script, ["full", out], SEED_BATCH=bad)
        assert refused == f"error: SEED_BATCH must be >= 1 (got '{bad}')"
