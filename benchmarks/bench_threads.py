"""How a deep learner's gradient step's time depends on torch's intra-op threads.

For each stacked model (the DSN's VDN on one-hot states, LBF's VDN and deep IQL on each
agent's own observation at EPyMARL's settings, the battlefield's QMIX on its features),
with 1 to ``--max-threads`` threads and several seed counts, the milliseconds of one
gradient step (autograd's, and the fused step where it covers the learner), and the
multiply-adds of the step's forward pass (:func:`cmarlcd.learners.deep.threads.step_work`)
beside them, so the work per thread below which more threads cost more can be read off.

    python benchmarks/bench_threads.py --max-threads 2 --seeds 1 5 30
    python benchmarks/bench_threads.py --threads 1 2 4 8 16 --seeds 1 30 --repeats 3
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from cmarlcd.learners.deep.config import DeepConfig
from cmarlcd.learners.deep.epymarl import epymarl_config
from cmarlcd.learners.deep.threads import step_work
from cmarlcd.learners.deep.value_decomposition import ValueDecomposition

#: (name, config, action counts, input size, own observation size or None, integer states)
MODELS = (
    ("DSN VDN (one-hot)", DeepConfig(mixer="vdn"), [3] * 13, 43, None, True),
    ("LBF 8x8 VDN (own obs, EPyMARL)", epymarl_config(DeepConfig(mixer="vdn"), 50),
     [6, 6], 12 + 2 * 12, 12, False),
    ("LBF 8x8 deep IQL (own obs, EPyMARL)", epymarl_config(DeepConfig(mixer="independent"), 50),
     [6, 6], 12 + 2 * 12, 12, False),
    ("battlefield QMIX (features)", DeepConfig(mixer="qmix", batch_size=720, buffer_size=100_000,
                                                 mixer_hidden=64), [6] * 6, 96, None, False),
)  # fmt: skip


def batch_of(model: ValueDecomposition, config: DeepConfig, in_dim: int, index: bool) -> dict:
    rng = torch.Generator().manual_seed(0)
    b, n, size = model.n_seeds, model.n_agents, config.batch_size
    if index:
        state = torch.randint(0, in_dim, (b, size), generator=rng)
        nxt = torch.randint(0, in_dim, (b, size), generator=rng)
    else:
        state = torch.randn(b, size, in_dim, generator=rng)
        nxt = torch.randn(b, size, in_dim, generator=rng)
    return {
        "state": state, "next_state": nxt,
        "actions": torch.randint(0, int(model.width), (b, size, n), generator=rng),
        "reward": torch.randn(b, size, generator=rng),
        "terminal": torch.zeros(b, size, dtype=torch.bool),
    }  # fmt: skip


def step_ms(model: ValueDecomposition, batch: dict, threads: int, repeats: int) -> float:
    torch.set_num_threads(threads)
    model.learn(batch)  # warm
    start = time.perf_counter()
    for _ in range(repeats):
        model.learn(batch)
    return 1e3 * (time.perf_counter() - start) / repeats


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--max-threads", type=int, default=os.cpu_count() or 1)
    p.add_argument("--threads", type=int, nargs="+", help="these counts instead of 1..max")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 5, 30])
    p.add_argument("--repeats", type=int, default=20)
    args = p.parse_args()
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch "
          f"{torch.__version__}, load {os.getloadavg()[0]:.2f}")  # fmt: skip
    threads = args.threads or list(range(1, args.max_threads + 1))
    print(f"{'model':38s} {'seeds':>5s} {'step':>8s} {'work (M)':>9s} "
          + " ".join(f"{t:>2d} thr ms" for t in threads))  # fmt: skip
    for name, config, counts, in_dim, own, index in MODELS:
        for seeds in args.seeds:
            for step in ("autograd", "fused"):
                chosen = DeepConfig(**{**config.__dict__, "step": step})
                if step == "fused" and not chosen.auto_fuses:
                    continue
                seqs = [np.random.SeedSequence(k) for k in range(seeds)]
                model = ValueDecomposition(counts, in_dim, chosen, seqs, own_dim=own)
                batch = batch_of(model, chosen, in_dim, index)
                times = [step_ms(model, batch, t, args.repeats) for t in threads]
                print(f"{name:38s} {seeds:5d} {step:>8s} {step_work(model) / 1e6:9.2f} "
                      + " ".join(f"{ms:9.2f}" for ms in times))  # fmt: skip


if __name__ == "__main__":
    main()
