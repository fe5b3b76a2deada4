"""Where a sweep's time went, part by part: ``reproduce``'s last table (and its JSON)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from cmarlcd.reports.section import Section, TableBlock, cells, new_section
from cmarlcd.runs import RunRecord


def duration_text(seconds: float) -> str:
    """``"3.4 s"``, ``"12 min 05 s"``, ``"1 h 02 min"``."""
    if seconds < 59.95:
        return f"{seconds:.1f} s"
    if round(seconds) < 3600:
        minutes, rest = divmod(round(seconds), 60)
        return f"{minutes} min {rest:02d} s"
    hours, minutes = divmod(round(seconds / 60), 60)
    return f"{hours} h {minutes:02d} min"


def part_times(records: Sequence[RunRecord], started: float) -> dict[str, float | int | None]:
    """One part's runs: how many, how many this command computed (stored since
    ``started``, seconds since the epoch), their own compute time (every run's wall time,
    whenever it was computed) and when this command stored the part's last run (seconds
    after ``started``; None when it computed none of them)."""
    now = [rec.finished_at for rec in records if rec.finished_at >= started]
    return {
        "runs": len(records),
        "computed_now": len(now),
        "compute_seconds": sum(rec.wall_seconds for rec in records),
        "done_after_seconds": max(now) - started if now else None,
    }


def time_section(
    parts: Mapping[str, Sequence[RunRecord]], started: float, wall_seconds: float, workers: int
) -> Section:
    """The time of each part of a sweep that began at ``started`` and took
    ``wall_seconds`` on ``workers`` workers. Parts share the workers (one sweep), so a
    part's wall time is not its own: the table gives each part's compute time (the sum
    of its runs' times, over the workers) and when its last run was done."""
    everything = [rec for records in parts.values() for rec in records]
    times = {name: part_times(records, started) for name, records in parts.items()}
    section = new_section(
        "Time by part",
        f"{workers} workers; this command {duration_text(wall_seconds)}",
        everything,
        time_by_part=times,
        wall_seconds=wall_seconds,
        workers=workers,
    )
    rows = []
    for name, t in times.items():
        done = t["done_after_seconds"]
        rows.append(
            cells(
                name,
                f"{t['runs']:,}",
                f"{t['computed_now']:,}",
                duration_text(float(t["compute_seconds"] or 0.0)),
                "—" if done is None else duration_text(float(done)),
            )
        )
    columns = ["part", "runs", "computed now", "compute time", "last run done after"]
    caption = (
        "compute time: the sum of the part's runs' own wall times, whenever computed (on "
        f"{workers} workers a part alone would take about that over {workers}); last run "
        "done after: since this command started, for the runs it computed"
    )
    section.add(TableBlock("", columns, rows, caption=caption))
    return section
