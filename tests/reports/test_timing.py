"""``reproduce``'s time by part: counts, compute time and when each part was done."""

from __future__ import annotations

import pytest

from cmarlcd.reports.timing import duration_text, part_times, time_section
from cmarlcd.runs import RunKey, RunRecord

STARTED = 1_000_000.0


def record(index: int, seconds: float, finished_at: float) -> RunRecord:
    key = RunKey("dsn", "cmarl-cd", "{}", 0, index)
    return RunRecord(key, {}, seconds, "test", finished_at)


@pytest.mark.parametrize(
    ("seconds", "text"),
    [
        (3.44, "3.4 s"),
        (59.97, "1 min 00 s"),
        (725, "12 min 05 s"),
        (3599.6, "1 h 00 min"),
        (4000, "1 h 07 min"),
    ],
)
def test_durations_read_in_the_largest_units_that_fit(seconds, text) -> None:
    assert duration_text(seconds) == text


def test_a_part_counts_the_runs_this_command_stored_and_all_their_compute_time() -> None:
    stored_before = record(0, 10.0, STARTED - 50)  # from an earlier command
    computed = [record(1, 20.0, STARTED + 30), record(2, 5.0, STARTED + 90)]
    times = part_times([stored_before, *computed], STARTED)
    assert times == {
        "runs": 3,
        "computed_now": 2,
        "compute_seconds": 35.0,
        "done_after_seconds": 90.0,
    }
    assert part_times([stored_before], STARTED)["done_after_seconds"] is None


def test_the_section_has_a_row_and_a_document_entry_per_part() -> None:
    parts = {"Table 1": [record(0, 1.0, STARTED + 2)], "Figs. 6-7": [record(1, 4000.0, 0.0)]}
    section = time_section(parts, STARTED, wall_seconds=130.0, workers=2)
    assert list(section.data["time_by_part"]) == ["Table 1", "Figs. 6-7"]
    rows = section.blocks[0].plain_rows()
    assert rows == [
        ["Table 1", "1", "1", "1.0 s", "2.0 s"],
        ["Figs. 6-7", "1", "0", "1 h 07 min", "—"],
    ]
    assert section.settings == "2 workers; this command 2 min 10 s"
