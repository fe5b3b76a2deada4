"""The report of the Theorem 1 check (``cmarl-cd theory``): where the ODE's starts
went, and the Jacobian's eigenvalues against eq. (13)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cmarlcd.reports.section import (
    FigureBlock,
    Section,
    TableBlock,
    TextBlock,
    cells,
    new_section,
)
from cmarlcd.runs import RunRecord


def theory_section(doc: dict[str, Any], records: Sequence[RunRecord] = ()) -> Section:
    """Where the ODE starts went, and the Jacobian's eigenvalues against eq. (13), of one
    Theorem 1 check (``records``: the stored run it comes from, if any)."""
    t = doc["temperature"]
    title = f"Theorem 1: {doc['n_agents']} agents, {doc['n_optima']} optimal joint actions"
    settings = f"T = {t:g}, {doc['starts']} random starts, seed {doc['seed']}"
    section = new_section(title, settings, records, **doc)
    reached = ", ".join(f"optimum {j}: {k}" for j, k in enumerate(doc["converged_to"]))
    section.add(
        TextBlock(
            f"ODE (8) from {doc['starts']} random interior starts -> {reached}; "
            f"elsewhere: {doc['unconverged']}"
        )
    )
    rows = [
        cells(str(j), f"{min(v):.8f} .. {max(v):.8f}", f"{doc['expected_eigenvalue']:g}")
        for j, v in enumerate(doc["eigenvalues_real"])
    ]
    section.add(
        TableBlock(
            "Jacobian of the reduced system (12) at each optimum, by finite differences",
            ["optimum", "eigenvalues (min .. max)", "paper, eq. (13)"],
            rows,
        )
    )
    verdict = "confirmed" if doc["confirmed"] else "NOT confirmed"
    section.add(TextBlock(f"max |eigenvalue + 2/T| = {doc['max_eigen_error']:.2e}: {verdict}"))
    if "figure" in doc:
        section.add(FigureBlock(Path(doc["figure"]), f"phase portrait of system (12), T = {t:g}"))
    return section
