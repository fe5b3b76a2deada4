"""Benchmark: the fused CPU gradient step of VDN and QMIX against PyTorch's autograd step.

One stacked step (B seeds, as the runner stacks them) on the tournament's shape (the
battlefield: 6 agents of 12 features → 49 → 6 actions, 720 transitions, QMIX mixer of 64)
and the DSN's (12 agents on 43 one-hot states → 49 → up to 5 actions, 400 transitions,
QMIX mixer of 70). Prints milliseconds per step for both, the ratio, and the rate of the
step's matrix products in GFLOP/s beside the machine's own matrix-product rate measured in
the same run (torch.bmm and NumPy on the step's first-layer shape, and one large product).

Then the DSN VDN step as a run meets it, after ``--trained-episodes`` episodes, both ways
(each model trained its own way); and the fused step of a model trained without the
flush (whose Adam moments have decayed into the subnormals where the batches missed a
parameter), as the fused step takes it (subnormals flushed to zero) and without the
flush, from the same state each time.

Usage: python benchmarks/bench_fused_step.py [--seeds B] [--repeats R]
           [--trained-episodes E]
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import os
import platform
import statistics
import time
from dataclasses import dataclass, replace

import numpy as np
import torch

from cmarlcd.games import battlefield
from cmarlcd.games import sensor_network as dsn
from cmarlcd.learners.deep.config import BATTLEFIELD_DEEP, DeepConfig
from cmarlcd.learners.deep.fused import step as fused_step
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition
from cmarlcd.training.deep import DeepBatch


@dataclass(frozen=True)
class Shape:
    """A step's shape: the game's agents and inputs and the learner's settings."""

    name: str
    counts: tuple[int, ...]
    in_dim: int
    index: bool
    config: DeepConfig

    def flops(self, seeds: int) -> float:
        """Floating-point operations of the step's matrix products (the reference count,
        as autograd computes them): for each agent network, the online and the target
        forward passes and the backward pass (two products per layer), and QMIX's
        hypernetworks on feature states likewise; one-hot inputs are tables of the states."""
        n, width, hidden = len(self.counts), max(self.counts), self.config.hidden
        rows = self.in_dim if self.index else self.config.batch_size
        first = 0 if self.index else self.in_dim * hidden  # one-hot: a row lookup
        agents = 2 * rows * (first + hidden * width) * 2 + 2 * rows * (first + 2 * hidden * width)
        total = n * agents
        if self.config.mixer == "qmix" and not self.index:
            units = self.config.mixer_hidden
            hyper = self.in_dim * (n * units + 3 * units)
            total += 2 * self.config.batch_size * hyper * 3  # online, target, gradient
        return float(seeds * total)


def shapes() -> list[Shape]:
    tour = DeepConfig(**BATTLEFIELD_DEEP)
    team = tuple(int(c) for c in battlefield.SPEC.action_counts[:6])
    out = []
    for mixer in ("vdn", "qmix"):
        out.append(
            Shape(
                f"tournament {mixer.upper()}",
                team,
                battlefield.SPEC.n_features,
                False,
                replace(tour, mixer=mixer),
            )
        )
        out.append(
            Shape(
                f"DSN {mixer.upper()}",
                tuple(int(c) for c in dsn.ACTION_COUNTS),
                dsn.N_STATE_INDICES,
                True,
                DeepConfig(mixer=mixer),
            )
        )
    return out


def batch_for(shape: Shape, seeds: int, rng: np.random.Generator) -> dict[str, torch.Tensor]:
    """A replay batch of the shape's kind (random states, actions, rewards, 5 % terminal)."""
    size = (seeds, shape.config.batch_size)
    n, width = len(shape.counts), max(shape.counts)
    if shape.index:
        state = rng.integers(0, shape.in_dim, (2, *size))
    else:
        state = rng.integers(0, 3, (2, *size, shape.in_dim)).astype(np.float32)
    batch = {
        "state": torch.as_tensor(state[0]),
        "next_state": torch.as_tensor(state[1]),
        "actions": torch.as_tensor(np.stack([rng.integers(0, c, size) for c in shape.counts], -1)),
        "reward": torch.as_tensor(rng.normal(size=size).astype(np.float32)),
        "terminal": torch.as_tensor(rng.random(size) < 0.05),
    }
    if not shape.index:
        batch["next_legal"] = torch.as_tensor(rng.random((*size, n, width)) < 0.8)
    return batch


def step_seconds(shape: Shape, seeds: int, repeats: int) -> dict[str, float]:
    """Median seconds of one step for each way, the two interleaved (so both see the same
    load), after a warm-up step each (compilation)."""
    sequences = [np.random.SeedSequence(k) for k in range(seeds)]
    batch = batch_for(shape, seeds, np.random.default_rng(0))
    models = {
        step: ValueDecomposition(
            shape.counts, shape.in_dim, replace(shape.config, step=step), sequences
        )
        for step in ("autograd", "fused")
    }
    times: dict[str, list[float]] = {step: [] for step in models}
    for model in models.values():
        model.td_step(batch)
    for _ in range(repeats):
        for step, model in models.items():
            start = time.perf_counter()
            model.td_step(batch)
            times[step].append(time.perf_counter() - start)
    return {step: statistics.median(values) for step, values in times.items()}


def product_rates(repeats: int) -> dict[str, float]:
    """GFLOP/s of the machine's matrix products: the tournament step's first layer for 60
    groups (10 seeds × 6 agents: 720 × 12 by 12 × 49) with torch.bmm and NumPy, and one
    1024 × 1024 product."""
    rng = np.random.default_rng(0)
    x = rng.random((60, 720, 12), dtype=np.float32)
    w = rng.random((60, 12, 49), dtype=np.float32)
    big = rng.random((1024, 1024), dtype=np.float32)
    tx, tw, tbig = torch.from_numpy(x), torch.from_numpy(w), torch.from_numpy(big)
    cases = {
        "torch.bmm, first-layer shape": (lambda: torch.bmm(tx, tw), 2 * x.size * 49),
        "numpy matmul, first-layer shape": (lambda: np.matmul(x, w), 2 * x.size * 49),
        "torch.mm, 1024 x 1024": (lambda: torch.mm(tbig, tbig), 2 * 1024**3),
    }
    rates = {}
    for name, (product, flops) in cases.items():
        product()
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            product()
            times.append(time.perf_counter() - start)
        rates[name] = flops / statistics.median(times) / 1e9
    return rates


def subnormal_seconds(seeds: int, repeats: int, episodes: int) -> tuple[dict[str, float], int]:
    """Median seconds of one fused DSN VDN step of a model trained for ``episodes``
    episodes without the flush (so its moments hold the subnormals a run kept before it),
    then stepped with the flush and without, interleaved, each from the trained state (its
    weights and moments restored before every step); and the subnormal first moments."""
    config = replace(DeepConfig(mixer="vdn"), step="fused")
    run = DeepBatch(dsn.SPEC, config, [np.random.SeedSequence(k) for k in range(seeds)], episodes)
    original = fused_step.subnormals_flushed
    fused_step.subnormals_flushed = contextlib.nullcontext  # trained as before the flush
    try:
        run.train([], lambda *args: None)
    finally:
        fused_step.subnormals_flushed = original
    step = run.group.model.fused
    state = [*step.flat[0], *step.flat[2], *step.flat[3]]
    saved = [array.copy() for array in state]
    tiny = np.finfo(np.float32).tiny
    subnormal = sum(int(((m != 0) & (np.abs(m) < tiny)).sum()) for m in step.flat[2])
    batches = [run.group.sample() for _ in range(repeats)]
    ways = {"flushed": fused_step.subnormals_flushed, "not flushed": contextlib.nullcontext}
    times: dict[str, list[float]] = {way: [] for way in ways}
    try:
        for batch in batches:
            for way, flush in ways.items():
                fused_step.subnormals_flushed = flush
                for array, kept in zip(state, saved, strict=True):
                    np.copyto(array, kept)
                start = time.perf_counter()
                step(batch)
                times[way].append(time.perf_counter() - start)
    finally:
        fused_step.subnormals_flushed = original
    return {way: statistics.median(values) for way, values in times.items()}, subnormal


def trained_seconds(seeds: int, repeats: int, episodes: int) -> dict[str, float]:
    """Median seconds of one DSN VDN step at each way, each on a model trained that way for
    ``episodes`` episodes (the state a real run's steps meet, the fused one with its
    flush), on batches drawn from its own replay, from its trained state every time
    (weights and optimiser restored between steps, outside the timing)."""
    out = {}
    for way in ("autograd", "fused"):
        config = replace(DeepConfig(mixer="vdn"), step=way)
        sequences = [np.random.SeedSequence(k) for k in range(seeds)]
        run = DeepBatch(dsn.SPEC, config, sequences, episodes)
        run.train([], lambda *args: None)
        model = run.group.model
        batches = [run.group.sample() for _ in range(repeats)]
        weights = copy.deepcopy(model.state_dict())
        optimiser = copy.deepcopy(model.optimizer.state_dict())
        moments = (
            [array.copy() for array in model.fused.flat[2] + model.fused.flat[3]]
            if model.fused
            else []
        )
        times = []
        for batch in batches:
            model.load_state_dict(weights)
            model.optimizer.load_state_dict(optimiser)
            if model.fused:
                for array, kept in zip(
                    model.fused.flat[2] + model.fused.flat[3], moments, strict=True
                ):
                    np.copyto(array, kept)
            start = time.perf_counter()
            model.learn(batch)
            times.append(time.perf_counter() - start)
        out[way] = statistics.median(times)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds stacked (the runner's 10)")
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument(
        "--trained-episodes", type=int, default=20000, help="DSN episodes before the last part"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}, "
        f"1 thread; {args.seeds} seeds stacked, median of {args.repeats} steps"
    )
    for name, rate in product_rates(args.repeats).items():
        print(f"matrix products, {name}: {rate:.1f} GFLOP/s")
    for shape in shapes():
        seconds = step_seconds(shape, args.seeds, args.repeats)
        flops = shape.flops(args.seeds)
        auto, fused = seconds["autograd"], seconds["fused"]
        print(
            f"{shape.name}: autograd {1e3 * auto:.2f} ms ({flops / auto / 1e9:.1f} GFLOP/s), "
            f"fused {1e3 * fused:.2f} ms ({flops / fused / 1e9:.1f} GFLOP/s), "
            f"{auto / fused:.2f}x"
        )
    trained = trained_seconds(args.seeds, args.repeats, args.trained_episodes)
    auto, fused = trained["autograd"], trained["fused"]
    print(
        f"DSN VDN after {args.trained_episodes:,} episodes of a run, each way trained its "
        f"own way: autograd {1e3 * auto:.2f} ms, fused {1e3 * fused:.2f} ms, {auto / fused:.2f}x"
    )
    seconds, subnormal = subnormal_seconds(args.seeds, args.repeats, args.trained_episodes)
    flushed, kept = seconds["flushed"], seconds["not flushed"]
    print(
        f"DSN VDN fused after {args.trained_episodes:,} episodes ({subnormal:,} first moments "
        f"subnormal): {1e3 * flushed:.2f} ms flushed, {1e3 * kept:.2f} ms not, "
        f"{kept / flushed:.2f}x"
    )


if __name__ == "__main__":
    main()
