"""The paper's claims about Figs. 6-7 (Section V-B), checked against stored matches:
each claim is one or more round-wise margins with their standard errors."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cmarlcd import registry
from cmarlcd.experiments.tournament_results import Cell, finite_mean, round_rates
from cmarlcd.runs import RunRecord

#: The verdicts of a claim: it holds beyond the noise, the opposite holds beyond the
#: noise, the rounds cannot tell, or the tournament lacks an algorithm it needs.
SUPPORTED, CONTRADICTED, NOT_SEPARATED, NOT_CHECKED = (
    "supported",
    "contradicted",
    "not separated",
    "not checked",
)
#: [choice] A claim's margin counts when it is more than this many standard errors (over
#: rounds) from 0.
STANDARD_ERRORS = 2.0
#: The paper's threshold for "wins under 40 % against CMARL-CD".
UNDER = 0.4


@dataclass(frozen=True)
class Margin:
    """One comparison behind a claim: the margin by which it holds (> 0: as the paper
    says), against whom, its standard error over rounds, and the rounds it rests on."""

    against: str
    value: float
    standard_error: float
    rounds: int

    @property
    def verdict(self) -> str:
        """SUPPORTED, CONTRADICTED or NOT_SEPARATED (:data:`STANDARD_ERRORS`)."""
        if self.rounds == 0:
            return NOT_SEPARATED
        if self.value > STANDARD_ERRORS * self.standard_error:
            return SUPPORTED
        if self.value < -STANDARD_ERRORS * self.standard_error:
            return CONTRADICTED
        return NOT_SEPARATED


@dataclass(frozen=True)
class Claim:
    """One claim of the paper (Section V-B) against our matches."""

    claim: str
    verdict: str
    """SUPPORTED, CONTRADICTED, NOT_SEPARATED or NOT_CHECKED."""
    evidence: str
    margins: tuple[Margin, ...] = ()
    """The comparisons it rests on (all must hold for SUPPORTED, one against it makes
    it CONTRADICTED)."""

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for margin in out["margins"]:
            for key in ("value", "standard_error"):
                if not math.isfinite(margin[key]):
                    margin[key] = None
        return out


#: The claims of Section V-B, in the order the paper makes them.
CLAIMS = (
    "CMARL-CD has the higher win rate against every other algorithm",
    "QMIX beats LA-OCA",
    "VDN beats LA-OCA",
    "QMIX wins under 40 % against CMARL-CD",
    "VDN wins under 40 % against CMARL-CD",
    "CMARL-CD needs the fewest win steps",
)


def _standard_error(values: np.ndarray) -> float:
    """The standard error of the mean of per-round values (infinite from one round)."""
    return float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else math.inf


def _margin(against: str, values: Sequence[float]) -> Margin:
    finite = np.array([v for v in values if not math.isnan(v)])
    if finite.size == 0:
        return Margin(against, math.nan, math.nan, 0)
    return Margin(against, float(finite.mean()), _standard_error(finite), int(finite.size))


def paired_margin(records: Sequence[RunRecord], a: str, b: str) -> Margin:
    """Per round, (win rate of a against b) - (win rate of b against a)."""
    mine, theirs = round_rates(records, a, b), round_rates(records, b, a)
    rounds = sorted(set(mine) & set(theirs))
    return _margin(b, [mine[r] - theirs[r] for r in rounds])


def _below(records: Sequence[RunRecord], a: str, b: str, threshold: float) -> Margin:
    """Per round, ``threshold`` minus the win rate of a against b."""
    return _margin(b, [threshold - rate for rate in round_rates(records, a, b).values()])


def _plus_minus(margin: Margin, scale: float = 100.0, unit: str = "") -> str:
    spread = STANDARD_ERRORS * margin.standard_error * scale
    return f"{margin.value * scale:+.1f}{unit} ± {spread:.1f}{unit}, {margin.rounds} rounds"


def _combined(text: str, margins: Sequence[Margin], evidence: str) -> Claim:
    verdicts = [m.verdict for m in margins]
    if all(v == SUPPORTED for v in verdicts):
        verdict = SUPPORTED
    elif any(v == CONTRADICTED for v in verdicts):
        verdict = CONTRADICTED
    else:
        verdict = NOT_SEPARATED
    return Claim(text, verdict, evidence, tuple(margins))


def check_claims(records: Sequence[RunRecord], cells: Sequence[Cell]) -> list[Claim]:
    """Each claim of :data:`CLAIMS`, with our numbers: a margin per comparison, counted
    when it is more than :data:`STANDARD_ERRORS` standard errors over rounds from 0."""
    table = {(c.algorithm, c.opponent): c for c in cells}
    names = {c.algorithm for c in cells}

    def missing(*required: str) -> Claim | None:
        lacking = [registry.display_name(n) for n in required if n not in names]
        return ", ".join(lacking) if lacking else None

    def unplayed(text: str, a: str, others: Sequence[str]) -> Claim | None:
        lacking = [o for o in others if (a, o) not in table or (o, a) not in table]
        if not lacking:
            return None
        pairs = ", ".join(
            f"{registry.display_name(a)} vs {registry.display_name(o)}" for o in lacking
        )
        return Claim(text, NOT_CHECKED, f"no match of {pairs}")

    def beats(text: str, a: str, others: Sequence[str]) -> Claim:
        if (why := unplayed(text, a, others)) is not None:
            return why
        margins = [paired_margin(records, a, o) for o in others]
        evidence = "; ".join(
            f"{registry.display_name(a)} wins {table[(a, m.against)].win_rate:.1%} against "
            f"{registry.display_name(m.against)}, which wins "
            f"{table[(m.against, a)].win_rate:.1%} (difference {_plus_minus(m, unit=' %')})"
            for m in margins
        )
        return _combined(text, margins, evidence)

    claims = []
    others = sorted(names - {"cmarl-cd"}, key=_rank)
    first = CLAIMS[0]
    if (lacking := missing("cmarl-cd")) or not others:
        why = f"needs {lacking} in the tournament" if lacking else "needs a second algorithm"
        claims.append(Claim(first, NOT_CHECKED, why))
    else:
        claims.append(beats(first, "cmarl-cd", others))
    for deep, text in (("qmix", CLAIMS[1]), ("vdn", CLAIMS[2])):
        if lacking := missing(deep, "la-oca"):
            claims.append(Claim(text, NOT_CHECKED, f"needs {lacking} in the tournament"))
        else:
            claims.append(beats(text, deep, ["la-oca"]))
    for deep, text in (("qmix", CLAIMS[3]), ("vdn", CLAIMS[4])):
        if lacking := missing(deep, "cmarl-cd"):
            claims.append(Claim(text, NOT_CHECKED, f"needs {lacking} in the tournament"))
            continue
        if (why := unplayed(text, deep, ["cmarl-cd"])) is not None:
            claims.append(why)
            continue
        margin = _below(records, deep, "cmarl-cd", UNDER)
        cell = table[(deep, "cmarl-cd")]
        evidence = (
            f"{cell.win_rate:.1%} ± {cell.win_rate_std:.1%} (spread); 40 % minus it: "
            f"{_plus_minus(margin, unit=' %')}"
        )
        claims.append(_combined(text, [margin], evidence))
    claims.append(_fewest_win_steps(records, names))
    return claims


def _fewest_win_steps(records: Sequence[RunRecord], names: set[str]) -> Claim:
    """CMARL-CD against each other algorithm X: per round, X's mean win steps over its
    opponents minus CMARL-CD's; the claim holds against X when that difference is more
    than two standard errors above 0."""
    text = CLAIMS[5]
    if "cmarl-cd" not in names or len(names) < 2:
        return Claim(text, NOT_CHECKED, "needs CMARL-CD and another algorithm")
    margins = [
        _margin(other, _win_step_differences(records, other, "cmarl-cd", sorted(names)))
        for other in sorted(names - {"cmarl-cd"}, key=_rank)
    ]
    evidence = "; ".join(
        f"{registry.display_name(m.against)}: no rounds won by both"
        if m.rounds == 0
        else f"{registry.display_name(m.against)} needs {m.value:+.2f} ± "
        f"{STANDARD_ERRORS * m.standard_error:.2f} turns more ({m.rounds} rounds)"
        for m in margins
    )
    return _combined(text, margins, evidence)


def _win_step_differences(
    records: Sequence[RunRecord], other: str, ours: str, opponents: Sequence[str]
) -> list[float]:
    """Per round: the mean win steps of ``other`` over its opponents minus those of
    ``ours`` (rounds where either won nothing are left out)."""

    def per_round(name: str) -> dict[int, float]:
        by_round: dict[int, list[float]] = defaultdict(list)
        for opponent in opponents:
            for r, steps in round_rates(records, name, opponent, "win_steps").items():
                by_round[r].append(steps)
        return {r: finite_mean(values) for r, values in by_round.items()}

    theirs, mine = per_round(other), per_round(ours)
    rounds = sorted(set(theirs) & set(mine))
    return [d for d in (theirs[r] - mine[r] for r in rounds) if not math.isnan(d)]


def _rank(name: str) -> int:
    known = list(registry.LEARNERS)
    return known.index(name) if name in known else len(known)
