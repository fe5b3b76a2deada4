"""Lockstep: does the fused step drift from autograd's faster than rounding does?

The equivalence study (``fused_equivalence.py``) compares the two steps' *results*; this
script looks for a systematic difference in the steps themselves, on the batches real
training feeds them: ``battlefield``, one VDN-vs-QMIX match; ``dsn``, one seed of deep
CMARL-CD on the DSN (its keyed update); ``lbf``, one seed each of VDN and QMIX at
EPyMARL's settings and model class (``cmarl-cd field --preset epymarl``, shared networks of
two hidden layers on their own observations, QMIX's two-layer hypernetworks) on
Level-Based Foraging's 8x8-2p-2f-coop, ``--episodes`` counting environment steps there.
It trains with autograd, records every batch and
target copy of each model, then replays that sequence into three copies of each model
as it started:

* ``autograd``: autograd's step (the reference, as in the match);
* ``fused``: the fused step;
* ``jittered``: autograd's step, its weights then moved by one float32 rounding (relative
  2^-23 normal noise) after every step: the drift that rounding alone causes.

At points along the sequence it prints:

* **one step**: from the reference's weights and Adam moments at that point, the largest
  difference between the weights after one fused step and after one autograd step, on
  that point's batch (float32 rounding of weights of order 0.1 to 1: 1e-8 to 1e-7);
* **distance**: each copy's distance to the reference's weights, relative to their norm;
* **agree**: the share of (state, agent) pairs where the copy's greedy action is the
  reference's (the battlefield: the states of the last 50 batches; the DSN: every state).

If the fused copy drifts no faster than the jittered one, the two steps differ by
rounding only, and a difference between their runs is the chaos of learning.

Usage:
    python benchmarks/fused_lockstep.py battlefield --episodes 20000
    python benchmarks/fused_lockstep.py dsn --episodes 20000
    python benchmarks/fused_lockstep.py lbf --episodes 100000
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import time

import numpy as np
import torch

from cmarlcd import registry
from cmarlcd.cli.field import evaluation_points, with_preset
from cmarlcd.experiments import games
from cmarlcd.experiments import tournament as tour
from cmarlcd.experiments.episodic import EpisodicRun, run_batch
from cmarlcd.games import battlefield, sensor_network
from cmarlcd.learners.deep.degree_model import DegreeModel
from cmarlcd.learners.deep.fused.step import FusedDegreeStep, FusedStep
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition
from cmarlcd.training.deep import DeepBatch
from cmarlcd.training.match import Match

JITTER = 2.0**-23  # float32's relative rounding


def record(game: str, episodes: int, seed: int) -> dict[int, dict]:
    """Train with autograd; per model: its starting copy and its events
    (``("learn", batch)`` or ``("sync", None)``) in order."""
    log: dict[int, dict] = {}
    kind = DegreeModel if game == "dsn" else ValueDecomposition
    learn, sync = kind.learn, kind.sync_target

    def entry(model) -> dict:
        if id(model) not in log:
            log[id(model)] = {"start": _copy(model), "events": [], "name": _name(model)}
        return log[id(model)]

    def recording_learn(model, batch):
        entry(model)["events"].append(("learn", {k: v.clone() for k, v in batch.items()}))
        return learn(model, batch)

    def recording_sync(model):
        entry(model)["events"].append(("sync", None))
        return sync(model)

    kind.learn, kind.sync_target = recording_learn, recording_sync
    try:
        _train(game, episodes, seed)
    finally:
        kind.learn, kind.sync_target = learn, sync
    return log


#: The LBF part's task and model class (EPyMARL's: shared, two hidden layers, QMIX's
#: hypernetworks of two layers).
LBF_TASK = "foraging:8x8-2p-2f-coop"
EPYMARL_MODEL = {"share": True, "hidden_layers": 2}


def _train(game: str, episodes: int, seed: int) -> None:
    """One autograd VDN-vs-QMIX match, one seed of deep CMARL-CD on the DSN, or one seed
    each of VDN and QMIX on LBF (``episodes`` counting steps)."""
    if game == "lbf":
        family, rules = games.parse_game(LBF_TASK)
        for name in ("vdn", "qmix"):
            (learner,) = with_preset((registry.LEARNERS[name],), "epymarl", rules.spec().max_steps)
            hypernets = {"hypernet_layers": 2} if name == "qmix" else {}
            learner = dataclasses.replace(learner, step="autograd", **EPYMARL_MODEL, **hypernets)
            options = family.options(rules, "own-observations")
            points = evaluation_points(episodes, episodes)
            run = EpisodicRun(learner, (episodes,), 1, points, 1, options, unit="steps")
            run_batch(family.game, run, [np.random.SeedSequence(seed)])
        return
    if game == "battlefield":
        learners = tour.battlefield_learners()
        env, a, b = np.random.default_rng(seed).spawn(3)
        pair = (learners["vdn"], learners["qmix"])
        Match(battlefield.SPEC, pair, env, (a, b), episodes).learn()
        return
    config = dataclasses.replace(registry.LEARNERS["deep-cmarl-cd"], step="autograd")
    run = DeepBatch(sensor_network.SPEC, config, [np.random.SeedSequence(seed)], episodes)
    run.train([], lambda *args: None)


def _name(model) -> str:
    if isinstance(model, ValueDecomposition):
        return model.config.mixer
    return "deep CMARL-CD"


def _copy(model):
    """A copy of the model as it is (weights, targets, optimiser), generators left out."""
    generators, model.generators = model.generators, None
    try:
        return copy.deepcopy(model)
    finally:
        model.generators = generators


def _params(model) -> list[torch.nn.Parameter]:
    """The parameters a step moves, in the fused step's order."""
    if isinstance(model, ValueDecomposition):
        return [*model.agents.parameters(), *model.mixer.parameters()]
    record = list(model.record.parameters()) if model.config.estimates_unseen else []
    return [*model.agents.parameters(), *record]


def fused_copy(model):
    """A copy of the autograd model that takes the fused step, with the model's Adam
    moments and step count."""
    out = _copy(model)
    out.config = dataclasses.replace(out.config, step="fused")
    out.fused = (FusedStep if isinstance(model, ValueDecomposition) else FusedDegreeStep)(out)
    _, _, first, second = out.fused.flat
    for k, p in enumerate(_params(model)):
        state = model.optimizer.state.get(p)
        if state:
            first[k][:] = state["exp_avg"].reshape(-1).numpy()
            second[k][:] = state["exp_avg_sq"].reshape(-1).numpy()
            out.fused.steps = int(state["step"])
    return out


def flat(model) -> torch.Tensor:
    """The online weights as one vector."""
    return torch.cat([p.detach().reshape(-1) for p in _params(model)])


def jitter(model, noise: torch.Generator) -> None:
    """Move the online weights by one float32 rounding, at random."""
    with torch.no_grad():
        for p in _params(model):
            p.mul_(1 + JITTER * torch.randn(p.shape, generator=noise))


def one_step_gap(reference, batch: dict[str, torch.Tensor]) -> float:
    """The largest weight difference after one fused and one autograd step from the
    reference's weights and moments (the reference is left as it is)."""
    by_autograd, by_fused = _copy(reference), fused_copy(reference)
    by_autograd.learn(batch)
    by_fused.learn(batch)
    return float((flat(by_autograd) - flat(by_fused)).abs().max())


def agreement(models: dict, states: torch.Tensor | None) -> dict[str, float]:
    """Share of (state, agent) pairs where each copy's greedy action is the reference's
    (at ``states``, or every integer state)."""
    with torch.no_grad():
        actions = {
            name: model.greedy(states) if states is not None else model.greedy_table()
            for name, model in models.items()
        }
    return {
        name: float((acts == actions["autograd"]).float().mean()) for name, acts in actions.items()
    }


def replay(name: str, side: dict, points: int) -> None:
    """Replay one side's events into its three copies, printing the drift."""
    models = {"autograd": _copy(side["start"]), "fused": fused_copy(side["start"])}
    models["jittered"] = _copy(side["start"])
    events = side["events"]
    steps = sum(kind == "learn" for kind, _ in events)
    states = None
    if isinstance(side["start"], ValueDecomposition):
        states = torch.cat([b["state"] for kind, b in events if kind == "learn"][-50:], dim=1)
    every = max(1, steps // points)
    print(f"{name} ({side['name']}): {steps:,} gradient steps, {len(events) - steps} target copies")
    print(
        f"  {'step':>6} {'loss':>7} {'one step':>9}   distance: {'fused':>8} {'jittered':>9}"
        f"   agree: {'fused':>7} {'jittered':>9}"
    )
    noise = torch.Generator().manual_seed(0)
    done, start = 0, time.perf_counter()
    for kind, batch in events:
        if kind == "sync":
            for model in models.values():
                model.sync_target()
            continue
        done += 1
        report = done % every == 0 or done == steps
        gap = one_step_gap(models["autograd"], batch) if report else 0.0
        loss = models["autograd"].learn(batch)
        models["fused"].learn(batch)
        models["jittered"].learn(batch)
        jitter(models["jittered"], noise)
        if report:
            reference = flat(models["autograd"])
            scale = float(reference.norm())
            far = {key: float((flat(models[key]) - reference).norm()) / scale for key in models}
            agree = agreement(models, states)
            print(
                f"  {done:6,} {loss:7.3f} {gap:9.1e}   distance: {far['fused']:8.1e} "
                f"{far['jittered']:9.1e}   agree: {agree['fused']:7.4f} {agree['jittered']:9.4f}",
                flush=True,
            )
    print(f"  ({time.perf_counter() - start:.0f} s)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("game", choices=("battlefield", "dsn", "lbf"))
    parser.add_argument("--episodes", type=int, default=20000, help="learning episodes played "
                        "(lbf: environment steps)")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--points", type=int, default=10, help="rows printed per side")
    args = parser.parse_args(argv)
    if args.episodes < 1 or args.points < 1:
        parser.error("--episodes and --points: at least 1")
    torch.set_num_threads(1)
    start = time.perf_counter()
    log = record(args.game, args.episodes, args.seed)
    print(f"recorded {args.episodes:,} episodes in {time.perf_counter() - start:.0f} s")
    for k, side in enumerate(log.values()):
        replay(f"side {k}", side, args.points)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
