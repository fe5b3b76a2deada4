"""``cmarl-cd evaluate``: a policy kept with ``--save-policies`` played greedily again."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from cmarlcd.cli.app import app
from cmarlcd.cli.options import JsonOption, fails_cleanly
from cmarlcd.cli.train import parse_env_kwargs
from cmarlcd.errors import require
from cmarlcd.sweeps.store import ResultStore


@app.command(short_help="Play a policy kept with --save-policies greedily again.")
@fails_cleanly
def evaluate(
    policy: Annotated[
        Path, typer.Option(help="A policy file kept by --save-policies (.npz or .safetensors).")
    ],
    episodes: Annotated[
        int | None,
        typer.Option(
            help="Greedy episodes [default: the run's own last evaluation, its episodes "
            "and seeds, which gives the store's last curve point].",
            show_default=False,
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(
            help="Seed of the episodes' resets (instead of the run's).", show_default=False
        ),
    ] = None,
    env: Annotated[
        str | None,
        typer.Option(
            help="Another environment of the same shapes, MODULE:FACTORY [default: the run's].",
            show_default=False,
        ),
    ] = None,
    env_kwargs: Annotated[
        str | None,
        typer.Option(help="Its keyword arguments, a JSON object.", show_default=False),
    ] = None,
    store: Annotated[
        Path | None,
        typer.Option(
            help="A results store holding the run: its stored figure is shown beside.",
            show_default=False,
        ),
    ] = None,
    as_json: JsonOption = False,
) -> None:
    """Play a kept greedy policy again and print its mean return (with the run's stored
    figure where --store holds the run)."""
    from cmarlcd.experiments.policy_evaluation import evaluate_policy, run_spec, stored_return
    from cmarlcd.policies import load_policy
    from cmarlcd.policies.files import load_partner

    kept = load_policy(policy)
    kwargs = None if env_kwargs is None else parse_env_kwargs(env_kwargs)
    part = kept.metadata.get("partner_part")  # a match's other team
    partner = None if part is None else load_partner(policy, kept, part)
    doc = evaluate_policy(kept, episodes, seed, env, kwargs, partner)
    if store is not None:
        require(store.is_file(), "store", f"{store}: no such results store")
        with ResultStore(store, create=False) as db:
            found = db.get([run_spec(kept.metadata).key])
        if "wins" in doc:
            doc["stored"] = stored_match(found[0]) if found else None
        else:
            doc["stored_return"] = stored_return(found[0]) if found else None
    if as_json:
        print(json.dumps({"policy": str(policy), **doc}, indent=2))
        return
    console = Console()
    if "wins" in doc:
        print_match(console, doc, store)
        return
    console.print(
        f"{doc['algorithm']} on {doc.get('env') or doc['game']}: mean greedy return "
        f"{doc['mean_return']:.4f} "
        f"(± {doc['std_return']:.4f} over {doc['episodes']} episodes, {doc['mean_steps']:.1f} "
        f"steps; {doc['seeds']})"
    )
    if store is not None:
        stored = doc["stored_return"]
        said = "not in it" if stored is None else f"{stored:.4f} at the run's last point"
        console.print(f"the store {store}: {said}")


def stored_match(record) -> dict:
    """A stored match's wins (team 0, team 1) and ties."""
    return {"wins": list(record.metrics["wins"]), "ties": int(record.metrics["ties"])}


def print_match(console: Console, doc: dict, store: Path | None) -> None:
    """A match's replayed evaluation, and the stored one where ``--store`` holds it."""
    (a, b), (wins_a, wins_b) = doc["learners"], doc["wins"]
    console.print(
        f"{doc['algorithm']} on the battlefield: team 0 ({a}) won {wins_a}, team 1 ({b}) "
        f"won {wins_b}, {doc['ties']} ties of {doc['episodes']} greedy episodes "
        f"({doc['mean_steps']:.1f} turns; {doc['seeds']})"
    )
    if store is not None:
        stored = doc["stored"]
        said = (
            "not in it"
            if stored is None
            else (f"won {stored['wins'][0]} and {stored['wins'][1]}, {stored['ties']} ties")
        )
        console.print(f"the store {store}: {said}")
