"""The repeated-game protocol (Section IV-C): cells, runs, aggregation."""

from __future__ import annotations

import pytest

from cmarlcd.errors import ConfigError
from cmarlcd.experiments import repeated as rep
from cmarlcd.experiments import settings_of
from cmarlcd.sweeps.runner import run_sweep
from cmarlcd.sweeps.store import ResultStore


def test_paper_protocol_has_36_cells_of_50_runs() -> None:
    table1, table2 = rep.paper_sweep(1), rep.paper_sweep(2)
    assert len(table1.cells()) == 24 and len(table2.cells()) == 12
    assert len(table1.specs()) + len(table2.specs()) == 36 * 50
    assert {(c.agents, c.actions) for c in table2.cells()} == {
        (n, m) for n in range(4, 8) for m in range(3, 6)
    }


def test_a_small_sweep_is_summarized_per_cell(tmp_path) -> None:
    sweep = rep.RepeatedSweep(case=1, agents=(2, 3), actions=(2,), runs=5, seed=3)
    with ResultStore(tmp_path / "s.sqlite") as store:
        run_sweep(sweep.specs(), store, workers=1)
        records = store.get(s.key for s in sweep.specs())
    cells = rep.summarize(records)
    assert [(c.agents, c.actions, c.runs) for c in cells] == [(2, 2, 5), (3, 2, 5)]
    for cell in cells:
        assert cell.success_rate == 1.0 and cell.converged_rate == 1.0
        assert cell.paper_success_rate == 1.0
        # at least ~ln(999)/(2δ) ≈ 86 reinforcements are needed to pass p > 0.999
        assert cell.median_games is not None and cell.median_games >= 86
    assert rep.table_title(records).startswith("Table 1")


def test_each_run_plays_a_fresh_game_of_its_case() -> None:
    specs = rep.RepeatedSweep(case=2, agents=(4,), actions=(3,), runs=2).specs()
    metrics = [rep.run_cell(settings_of(s), s.seed_sequence()) for s in specs]
    assert [m["optima"] for m in metrics] == [8, 8]  # round(0.1 * 3^4)
    assert metrics[0] != metrics[1]
    assert rep.run_cell(settings_of(specs[0]), specs[0].seed_sequence()) == metrics[0]


@pytest.mark.parametrize(
    ("kwargs", "parameter"),
    [
        ({"case": 3}, "case"),
        ({"agents": (1, 2)}, "agents"),
        ({"actions": (1,)}, "actions"),
        ({"runs": 0}, "runs"),
        ({"seed": -1}, "seed"),
        ({"agents": (20,), "actions": (5,)}, "agents"),
    ],
)
def test_bad_sweeps_are_rejected(kwargs: dict, parameter: str) -> None:
    arguments = {"case": 1, "agents": (2,), "actions": (2,), **kwargs}
    with pytest.raises(ConfigError) as info:
        rep.RepeatedSweep(**arguments)
    assert info.value.parameter == parameter
